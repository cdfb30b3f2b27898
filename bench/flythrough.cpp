// Benchmark `flythrough`: the streaming manager over the 4096 m x 4096 m world (64 x 64 cells of 64 m)
// at camera speeds from walking to aircraft, with a time-of-day sweep.
// Two sources:
// - default: SyntheticCellSource (analytic light field, raw FP32 resident format, 8 m probe spacing, 3
//   layers, 8 x 8 radiance / 4 x 4 irradiance maps) along the closed loop: the streaming decisions,
//   budgets and fallback coverage, not decode cost. IO model: inline loads, at most `--loads-per-frame`
//   cells per 60 fps frame (deterministic: identical decisions on every machine).
// - `--world DIR` (bench/flythrough_baked.sh): the baked cell files of DIR (CellFileSource: read +
//   checks + generator decode per load on `--io-threads` threads, relight = re-decode at the new time of
//   day, fallback = the files' per-key SH L1) along `--path` (the bake's `lfgi bake --path`), frames paced
//   to real time: what a game sees, decode cost included.
// Rows: one per speed; frames.csv: every frame of the 50 m/s flight (the profile charts).
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <fstream>
#include <string>

#include <fmt/format.h>

#include "bench/bench_output.h"
#include "core/error.h"
#include "core/file_util.h"
#include "streaming/cell_file_source.h"
#include "streaming/flythrough.h"

namespace lfgi::bench {
namespace {

double peakRssMb() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return 0.0;
}

// Command-line options; those left at 0 / empty get the source's defaults (openSource).
struct Options {
  std::string out = "out/bench/flythrough";
  bool quick = false;
  int loadsPerFrame = 1;
  double budgetMb = 0.0;
  std::string world, path, decoder = "auto";
  std::vector<float> speeds;
  int ioThreads = 2;
  float seconds = 0.0f, decodeRadius = 0.0f;

  bool baked() const { return !world.empty(); }
};

void addOptions(CLI::App& app, Options& opt) {
  app.add_option("--out", opt.out, "Output directory");
  app.add_flag("--quick", opt.quick, "20 s flights instead of 60 s (baked world: 15 s instead of 30 s)");
  app.add_option("--loads-per-frame", opt.loadsPerFrame,
                 "Synthetic cells: IO bandwidth, cells per 60 fps frame")
      ->capture_default_str();
  app.add_option("--budget-mb", opt.budgetMb,
                 "Resident memory budget, MB (default 96; with --world 1024: every slot is the largest "
                 "decoded cell, ~22.6 MB for a 15k-probe city cell in FP32)");
  app.add_option("--world", opt.world,
                 "Fly over this world's baked cell files (DIR/baked/cells) instead of synthetic cells");
  app.add_option("--path", opt.path, "Path: loop or line (default: loop; with --world: line)")
      ->check(CLI::IsMember({"loop", "line"}));
  app.add_option("--speeds", opt.speeds,
                 "Camera speeds, m/s (default: 2 ... 1600; with --world: 2,10,25,50,100)")
      ->delimiter(',');
  app.add_option("--seconds", opt.seconds,
                 "Simulated seconds per flight (default: 60 / 20 quick; with --world 30 / 15)");
  app.add_option("--io-threads", opt.ioThreads, "With --world: IO threads reading + decoding cells")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  app.add_option("--decoder", opt.decoder, "With --world: generator decode cpu, gpu or auto")
      ->capture_default_str();
  app.add_option("--decode-radius", opt.decodeRadius,
                 "Decode radius, m (default: the manager's 160; with --world 128 = the path bake's radius)");
}

// The flights' cell source; `files` is set for a baked world (its read and decode time counters).
struct Source {
  std::unique_ptr<streaming::CellSource> ptr;
  streaming::CellFileSource* files = nullptr;
};

// Opens the baked cell files or the synthetic cells, names the device and fills the defaults of `opt`.
Source openSource(Options& opt, BenchOutput& o) {
  Source source;
  if (opt.baked()) {
    streaming::CellFileSourceOptions fso;
    fso.worldDir = opt.world;
    fso.decoder = streaming::parseDecoderChoice(opt.decoder);
    auto f = std::make_unique<streaming::CellFileSource>(fso);
    source.files = f.get();
    source.ptr = std::move(f);
    o.setDevice(fmt::format("{} decode ({}), {} IO threads", source.files->selection().backend,
                            source.files->selection().device, opt.ioThreads));
    if (opt.path.empty()) opt.path = "line";
    if (opt.speeds.empty()) opt.speeds = {2, 10, 25, 50, 100};
    if (opt.seconds <= 0.0f) opt.seconds = opt.quick ? 15.0f : 30.0f;
    if (opt.decodeRadius <= 0.0f) opt.decodeRadius = 128.0f;
    if (opt.budgetMb <= 0.0) opt.budgetMb = 1024.0;
  } else {
    o.setDevice("cpu (streaming logic; synthetic cells)");
    streaming::SyntheticSourceOptions src;
    src.layout = {{0.0f, 0.0f}, 64.0f, {64, 64}};
    src.probeSpacing = 8.0f;
    src.layers = 3;
    src.resolution = 8;
    src.irradianceResolution = 4;
    source.ptr = std::make_unique<streaming::SyntheticCellSource>(src);
    if (opt.path.empty()) opt.path = "loop";
    if (opt.speeds.empty()) opt.speeds = {2, 10, 25, 50, 100, 200, 400, 800, 1600};
    if (opt.seconds <= 0.0f) opt.seconds = opt.quick ? 20.0f : 60.0f;
    if (opt.budgetMb <= 0.0) opt.budgetMb = 96.0;
  }
  return source;
}

void setColumns(BenchOutput& o) {
  o.setColumns({"speed_mps",         "frames",          "frames_missing_gi", "fallback_fraction",
                "p50_frame_ms",      "p95_frame_ms",    "p99_frame_ms",      "p99_update_ms",
                "p99_io_ms",         "p99_activate_ms", "p99_shade_ms",      "peak_resident_mb",
                "cells_loaded",      "cells_evicted",   "cells_relit",       "cells_loaded_per_km",
                "p95_relight_io_ms", "cells_failed",    "read_ms",           "decode_ms"});
}

// What the speed sweep gathers for summary.json and frames.csv.
struct Sweep {
  float maxOk = 0.0f;
  bool stillOk = true;
  nlohmann::ordered_json at50, perSpeed = nlohmann::ordered_json::object();
  std::string frames50;
};

streaming::FlythroughOptions flightOptions(const Options& opt, float v) {
  streaming::FlythroughOptions fo;
  fo.path = opt.path;
  fo.speed = v;
  fo.seconds = opt.seconds;
  fo.streaming.memoryBudgetBytes = size_t(opt.budgetMb * 1024 * 1024);
  if (opt.decodeRadius > 0.0f) {
    fo.streaming.decodeRadius = opt.decodeRadius;
    fo.streaming.keepRadius = 1.4f * opt.decodeRadius;
  }
  if (opt.baked()) {
    fo.streaming.ioThreads = opt.ioThreads;
    fo.realtime = true;  // loads and relights race the wall clock, as in a game
  } else {
    fo.streaming.ioThreads = 0;
    fo.streaming.maxInlineLoadsPerFrame = opt.loadsPerFrame;
  }
  return fo;
}

// results.csv's row of one flight; read0 / decode0: the source's counters before it.
void addSpeedRow(BenchOutput& o, float v, const streaming::FlythroughSummary& s, double km,
                 const streaming::CellFileSource* files, double read0, double decode0) {
  o.addRow({bench::num(v),
            bench::num(s.frames),
            bench::num(s.framesMissingGi),
            bench::num(s.fallbackFraction),
            bench::num(s.p50FrameMs),
            bench::num(s.p95FrameMs),
            bench::num(s.p99FrameMs),
            bench::num(s.p99UpdateMs),
            bench::num(s.p99IoMs),
            bench::num(s.p99ActivateMs),
            bench::num(s.p99ShadeMs),
            bench::num(double(s.peakBytesResident) / 1e6),
            bench::num(double(s.cellsRequested)),
            bench::num(double(s.cellsEvicted)),
            bench::num(double(s.cellsRelit)),
            bench::num(km > 0 ? double(s.cellsRequested) / km : 0.0),
            bench::num(s.p95RelightIoMs),
            bench::num(double(s.cellsFailed)),
            bench::num(files ? files->readMsTotal() - read0 : 0.0),
            bench::num(files ? files->decodeMsTotal() - decode0 : 0.0)});
}

// summary.json's per_speed entry of one flight.
nlohmann::ordered_json speedJson(const streaming::FlythroughSummary& s) {
  return {{"frames", s.frames},
          {"frames_missing_gi", s.framesMissingGi},
          {"fallback_fraction", s.fallbackFraction},
          {"frame_ms", {s.p50FrameMs, s.p95FrameMs, s.p99FrameMs}},
          {"update_ms", {s.p50UpdateMs, s.p95UpdateMs, s.p99UpdateMs}},
          {"io_ms", {s.p50IoMs, s.p95IoMs, s.p99IoMs}},
          {"activate_ms", {s.p50ActivateMs, s.p95ActivateMs, s.p99ActivateMs}},
          {"relight_ms", {s.p50RelightMs, s.p95RelightMs, s.p99RelightMs}},
          {"shade_ms", {s.p50ShadeMs, s.p95ShadeMs, s.p99ShadeMs}},
          {"relight_io_ms_p50_p95", {s.p50RelightIoMs, s.p95RelightIoMs}},
          {"peak_resident_mb", double(s.peakBytesResident) / 1e6},
          {"cells_loaded", s.cellsRequested},
          {"cells_relit", s.cellsRelit},
          {"cells_evicted", s.cellsEvicted},
          {"cells_failed", s.cellsFailed}};
}

// One flight at speed v: its row, log line and per_speed entry; the 50 m/s flight also its frames.
void flySpeed(float v, const Options& opt, const Source& source, BenchOutput& o, Sweep& sweep) {
  const streaming::FlythroughOptions fo = flightOptions(opt, v);
  const streaming::CellFileSource* files = source.files;
  const double read0 = files ? files->readMsTotal() : 0.0, decode0 = files ? files->decodeMsTotal() : 0.0;
  std::string csv;
  if (v == 50.0f)
    csv =
        "frame,resident_cells,loading_cells,bytes_resident,update_ms,shade_ms,fallback_fraction,io_ms,"
        "relight_ms,relight_io_ms,time_of_day,read_ms,decode_ms\n";
  // read_ms / decode_ms: the source's file read + checks and decode time accrued during the frame (IO
  // threads; baked cells only; frame 0 also holds the preload before the first frame).
  double lastRead = read0, lastDecode = decode0;
  streaming::FlythroughSummary s =
      streaming::runFlythrough(*source.ptr, fo, [&](const streaming::FlythroughFrame& f) {
        const double r = files ? files->readMsTotal() : 0.0, d = files ? files->decodeMsTotal() : 0.0;
        if (v == 50.0f)
          csv +=
              fmt::format("{},{},{},{},{:.4f},{:.4f},{:.5f},{:.3f},{:.4f},{:.3f},{:.4f},{:.3f},{:.3f}\n",
                          f.index, f.stats.resident, f.stats.loading, f.stats.bytesResident, f.stats.updateMs,
                          f.shadeMs, f.fallbackFraction(), f.stats.ioMs, f.stats.relightMs,
                          f.stats.relightIoMs, f.timeOfDay, r - lastRead, d - lastDecode);
        lastRead = r, lastDecode = d;
      });
  if (s.interrupted) fail("interrupted");
  const double km = double(v) * fo.seconds / 1000.0;
  addSpeedRow(o, v, s, km, files, read0, decode0);
  spdlog::info(
      "{:6.0f} m/s: fallback {:.3f} %, missing-GI frames {}, p99 frame {:.2f} ms, peak {:.1f} MB, {} "
      "cells",
      v, 100.0 * s.fallbackFraction, s.framesMissingGi, s.p99FrameMs, double(s.peakBytesResident) / 1e6,
      s.cellsRequested);
  sweep.perSpeed[fmt::format("{:g}", v)] = speedJson(s);
  if (sweep.stillOk && s.fallbackFraction <= 0.01 && s.framesMissingGi == 0)
    sweep.maxOk = v;
  else
    sweep.stillOk = false;
  if (v == 50.0f) {
    sweep.frames50 = csv;
    sweep.at50 = {{"frames", s.frames},
                  {"frames_missing_gi", s.framesMissingGi},
                  {"fallback_fraction", s.fallbackFraction},
                  {"p99_frame_ms", s.p99FrameMs}};
  }
}

// summary.json: the 50 m/s flight's headline, the world and IO model, every speed's entry.
void writeSummary(BenchOutput& o, const Options& opt, const Source& source,
                  const streaming::WorldLayout& layout, Sweep& sweep) {
  const bool baked = opt.baked();
  const streaming::CellFileSource* files = source.files;
  auto& j = o.summary();
  j["world_km2"] = double(layout.cells.x) * layout.cells.y * layout.cellSize * layout.cellSize / 1e6;
  j["path"] = opt.path;
  j["path_km"] = streaming::flightPathLength(layout, streaming::FlythroughOptions{.path = opt.path}) / 1000.0;
  j["seconds_per_flight"] = opt.seconds;
  j["source"] = baked ? fmt::format("baked cell files of {} ({} valid, {} missing, {} corrupt)", opt.world,
                                    files->validCells(), files->missingCells(), files->corruptCells())
                      : std::string("synthetic analytic cells");
  // Non-const at50: operator[] adds null entries when no flight was at 50 m/s.
  nlohmann::ordered_json& at50 = sweep.at50;
  j["frames"] = at50["frames"];
  j["frames_missing_gi"] = at50["frames_missing_gi"];
  j["fallback_fraction"] = at50["fallback_fraction"];
  j["max_speed_mps_with_fallback_le_1pct"] = sweep.maxOk;
  if (!baked) {
    j["bytes_per_km2"] = double(source.ptr->maxCellBytes()) * (1e6 / (64.0 * 64.0));
    j["bytes_per_km2_note"] = "synthetic cells in the raw FP32 resident format; codec bytes: bench codec";
  }
  j["p99_frame_ms"] = at50["p99_frame_ms"];
  j["per_speed_note"] =
      "stage times are [p50, p95, p99] over the flight's frames (io: IO-thread load time of the loads "
      "completed in a frame, read + checks + decode; relight_io: re-decode at the new time of day)";
  j["per_speed"] = sweep.perSpeed;
  j["peak_rss_mb"] = peakRssMb();
  j["io_model"] =
      baked
          ? fmt::format("{} IO threads (read + checks + {} decode), frames paced to real time; budget {} MB",
                        opt.ioThreads, files->selection().backend, opt.budgetMb)
          : fmt::format("inline loads, {} cell(s) per 60 fps frame; budget {} MB", opt.loadsPerFrame,
                        opt.budgetMb);
}

}  // namespace
}  // namespace lfgi::bench

int main(int argc, char** argv) {
  using namespace lfgi;
  CLI::App app{"lfgi benchmark: streaming fly-through"};
  bench::Options opt;
  bench::addOptions(app, opt);
  CLI11_PARSE(app, argc, argv);
  try {
    bench::BenchOutput o(opt.out, opt.quick);
    const bench::Source source = bench::openSource(opt, o);
    const streaming::WorldLayout layout = source.ptr->layout();
    bench::setColumns(o);
    bench::Sweep sweep;
    for (float v : opt.speeds) bench::flySpeed(v, opt, source, o, sweep);
    writeFileAtomic(std::filesystem::path(opt.out) / "frames.csv", sweep.frames50);
    bench::writeSummary(o, opt, source, layout, sweep);
    o.save();
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
