// Benchmark `flythrough`: the streaming manager over the 4096 m x 4096 m world (64 x 64 cells of 64 m)
// along the closed loop path, at camera speeds from walking to aircraft, with a time-of-day sweep.
// Cells: SyntheticCellSource (analytic light field, raw FP32 resident format, 8 m probe spacing, 3 layers,
// 8 x 8 radiance / 4 x 4 irradiance maps) until baked codec cells exist: the benchmark measures the
// streaming decisions, budgets and fallback coverage, not decode cost. IO model: inline loads, at most
// `--loads-per-frame` cells per 60 fps frame (deterministic: identical decisions on every machine).
// Rows: one per speed; frames.csv: every frame of the 50 m/s flight (the profile charts).
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <fstream>
#include <string>

#include <fmt/format.h>

#include "bench/bench_output.h"
#include "core/error.h"
#include "core/file_util.h"
#include "streaming/flythrough.h"

namespace {

double peakRssMb() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return 0.0;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace lfgi;
  CLI::App app{"lfgi benchmark: streaming fly-through"};
  std::string out = "out/bench/flythrough";
  bool quick = false;
  int loadsPerFrame = 1;
  double budgetMb = 96.0;
  app.add_option("--out", out, "Output directory");
  app.add_flag("--quick", quick, "20 s flights instead of 60 s");
  app.add_option("--loads-per-frame", loadsPerFrame, "IO bandwidth: cells per 60 fps frame")->capture_default_str();
  app.add_option("--budget-mb", budgetMb, "Resident memory budget, MB")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    bench::BenchOutput o(out, quick);
    o.setDevice("cpu (streaming logic; synthetic cells)");
    streaming::SyntheticSourceOptions src;
    src.layout = {{0.0f, 0.0f}, 64.0f, {64, 64}};
    src.probeSpacing = 8.0f;
    src.layers = 3;
    src.resolution = 8;
    src.irradianceResolution = 4;
    streaming::SyntheticCellSource source(src);
    o.setColumns({"speed_mps", "frames", "frames_missing_gi", "fallback_fraction", "p50_frame_ms", "p95_frame_ms",
                  "p99_frame_ms", "p99_update_ms", "p99_io_ms", "p99_activate_ms", "p99_shade_ms",
                  "peak_resident_mb", "cells_loaded", "cells_evicted", "cells_relit", "cells_loaded_per_km"});
    const std::vector<float> speeds = {2, 10, 25, 50, 100, 200, 400, 800, 1600};
    float maxOk = 0.0f;
    bool stillOk = true;
    nlohmann::ordered_json at50;
    std::string frames50;
    for (float v : speeds) {
      streaming::FlythroughOptions fo;
      fo.speed = v;
      fo.seconds = quick ? 20.0f : 60.0f;
      fo.streaming.ioThreads = 0;
      fo.streaming.maxInlineLoadsPerFrame = loadsPerFrame;
      fo.streaming.memoryBudgetBytes = size_t(budgetMb * 1024 * 1024);
      std::string csv;
      if (v == 50.0f)
        csv = "frame,resident_cells,loading_cells,bytes_resident,update_ms,shade_ms,fallback_fraction\n";
      streaming::FlythroughSummary s = streaming::runFlythrough(source, fo, [&](const streaming::FlythroughFrame& f) {
        if (v == 50.0f)
          csv += fmt::format("{},{},{},{},{:.4f},{:.4f},{:.5f}\n", f.index, f.stats.resident, f.stats.loading,
                             f.stats.bytesResident, f.stats.updateMs, f.shadeMs, f.fallbackFraction());
      });
      if (s.interrupted) fail("interrupted");
      const double km = double(v) * fo.seconds / 1000.0;
      o.addRow({bench::num(v), bench::num(s.frames), bench::num(s.framesMissingGi), bench::num(s.fallbackFraction),
                bench::num(s.p50FrameMs), bench::num(s.p95FrameMs), bench::num(s.p99FrameMs), bench::num(s.p99UpdateMs),
                bench::num(s.p99IoMs), bench::num(s.p99ActivateMs), bench::num(s.p99ShadeMs),
                bench::num(double(s.peakBytesResident) / 1e6), bench::num(double(s.cellsRequested)),
                bench::num(double(s.cellsEvicted)), bench::num(double(s.cellsRelit)),
                bench::num(km > 0 ? double(s.cellsRequested) / km : 0.0)});
      spdlog::info("{:6.0f} m/s: fallback {:.3f} %, missing-GI frames {}, p99 frame {:.2f} ms, peak {:.1f} MB, {} cells",
                   v, 100.0 * s.fallbackFraction, s.framesMissingGi, s.p99FrameMs, double(s.peakBytesResident) / 1e6,
                   s.cellsRequested);
      if (stillOk && s.fallbackFraction <= 0.01 && s.framesMissingGi == 0) maxOk = v;
      else stillOk = false;
      if (v == 50.0f) {
        frames50 = csv;
        at50 = {{"frames", s.frames}, {"frames_missing_gi", s.framesMissingGi}, {"fallback_fraction", s.fallbackFraction},
                {"p99_frame_ms", s.p99FrameMs}};
      }
    }
    writeFileAtomic(std::filesystem::path(out) / "frames.csv", frames50);
    auto& j = o.summary();
    j["world_km2"] = 4.096 * 4.096;
    j["frames"] = at50["frames"];
    j["frames_missing_gi"] = at50["frames_missing_gi"];
    j["fallback_fraction"] = at50["fallback_fraction"];
    j["max_speed_mps_with_fallback_le_1pct"] = maxOk;
    j["bytes_per_km2"] = double(source.maxCellBytes()) * (1e6 / (64.0 * 64.0));
    j["bytes_per_km2_note"] = "synthetic cells in the raw FP32 resident format; codec bytes: bench codec";
    j["p99_frame_ms"] = at50["p99_frame_ms"];
    j["peak_rss_mb"] = peakRssMb();
    j["io_model"] = fmt::format("inline loads, {} cell(s) per 60 fps frame; budget {} MB", loadsPerFrame, budgetMb);
    o.save();
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
