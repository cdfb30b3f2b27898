// `lfgi fly` and `lfgi profile`: the streaming manager over a whole world along a camera path.
// Cells come from the baked cell files when --world DIR has DIR/baked/cells (CellFileSource: OpenVDB
// cell files decoded at load by --decoder cpu | gpu | auto), else from SyntheticCellSource (an analytic light
// field on the world's cell layout, or the 4096 m default without --world). The summary says which. --relight
// vir wraps the source in streaming::VirRelightSource (GPU VIR relight of the world's surfels, relit on
// arrival and when the time of day / weather moves).
#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "app/commands.h"
#include "app/fly_render.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/progress.h"
#include "core/trace.h"
#include "gpu/context.h"
#include "streaming/cell_file_source.h"
#include "streaming/flythrough.h"
#include "streaming/http_region_source.h"
#include "streaming/vir_relight_source.h"
#include "worlds/world_cells.h"

namespace lfgi::app {

namespace {

double peakRssMb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
}

std::string framesCsv(const std::vector<streaming::FlythroughFrame>& frames) {
  std::string s =
      "frame,time_s,x_m,z_m,time_of_day_h,resident_cells,loading_cells,requested,activated,evicted,relit,"
      "failed,"
      "bytes_resident,io_ms,activate_ms,relight_ms,update_ms,shade_ms,frame_ms,visible_samples,fallback_"
      "fraction,"
      "missing_samples\n";
  for (const auto& f : frames)
    s += fmt::format(
        "{},{:.4f},{:.2f},{:.2f},{:.3f},{},{},{},{},{},{},{},{},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{},"
        "{:.5f},{}\n",
        f.index, f.timeS, f.position.x, f.position.z, f.timeOfDay, f.stats.resident, f.stats.loading,
        f.stats.requested, f.stats.activated, f.stats.evicted, f.stats.relit, f.stats.failed,
        f.stats.bytesResident, f.stats.ioMs, f.stats.activateMs, f.stats.relightMs, f.stats.updateMs,
        f.shadeMs, f.frameMs, f.visibleSamples, f.fallbackFraction(), f.missingSamples);
  return s;
}

// Charts of the profile: memory and cells per frame, stage time per frame against the budget.
constexpr const char* kProfileGnuplot = R"(set datafile separator ','
set terminal pngcairo size 1100,800 font ',10' noenhanced
set output png
set multiplot layout rows,1 title 'lfgi streaming profile: '.title
set xlabel 'frame'
set ylabel 'MB'
set y2label 'cells'
set ytics nomirror
set y2tics
set key top left
plot dir.'/frames.csv' every ::1 using 1:($13/1e6) with lines lw 2 title 'resident MB', \
     budget_mb with lines dt 2 lw 2 title 'memory budget MB', \
     '' every ::1 using 1:6 axes x1y2 with lines title 'resident cells', \
     '' every ::1 using 1:7 axes x1y2 with lines title 'loading cells'
set ylabel 'ms'
unset y2label
unset y2tics
plot dir.'/frames.csv' every ::1 using 1:14 with lines title 'IO (loads finished)', \
     '' every ::1 using 1:15 with lines title 'activate', \
     '' every ::1 using 1:16 with lines title 'relight', \
     '' every ::1 using 1:18 with lines title 'shade samples', \
     '' every ::1 using 1:19 with lines lw 2 title 'frame (update + shade)', \
     activate_budget_ms with lines dt 2 title 'activate budget'
set ylabel 'fallback fraction of visible samples'
set yrange [0:1]
plot dir.'/frames.csv' every ::1 using 1:21 with lines lw 2 title 'fallback fraction', 0.01 with lines dt 2 title '1 %'
)";
// With --render: the rendered frames' device time (GPU timestamps) per flight frame.
constexpr const char* kRenderGnuplot = R"(set ylabel 'device ms'
set autoscale y
plot dir.'/render_frames.csv' every ::1 using 2:4 with linespoints title 'G-buffer (GPU)', \
     '' every ::1 using 2:5 with linespoints lw 2 title 'probe shading (GPU)'
)";

// The decoder used, what `auto` measured, and the flight's generator-cell decodes (ms per load, probes/s).
nlohmann::ordered_json decoderJson(const streaming::CellFileSource& source) {
  const streaming::DecoderSelection& sel = source.selection();
  std::vector<double> ms;
  double probes = 0.0, totalMs = 0.0;
  for (const auto& d : source.decodeSamples())
    if (d.probes > 0) {
      ms.push_back(d.ms);
      probes += double(d.probes);
      totalMs += d.ms;
    }
  std::sort(ms.begin(), ms.end());
  auto pct = [&ms](double q) {
    return ms.empty() ? 0.0 : ms[std::min(ms.size() - 1, size_t(q * double(ms.size())))];
  };
  nlohmann::ordered_json j;
  j["requested"] = streaming::decoderChoiceName(sel.requested);
  j["backend"] = sel.backend;
  j["device"] = sel.device;
  j["reason"] = sel.reason;
  j["auto_cpu_probes_per_s"] = sel.cpuProbesPerS;
  j["auto_gpu_probes_per_s"] = sel.gpuProbesPerS;
  j["auto_measured_probes"] = sel.measuredProbes;
  j["generator_decodes"] = ms.size();
  j["p50_generator_decode_ms"] = pct(0.5);
  j["p95_generator_decode_ms"] = pct(0.95);
  j["generator_decode_probes_per_s"] = totalMs > 0.0 ? probes / (totalMs * 1e-3) : 0.0;
  return j;
}

// The cell sources of a flight: baked cell files or synthetic cells on the world's layout, optionally
// wrapped by the VIR relight (members in the order they are made, so they are destroyed in reverse).
struct FlySources {
  streaming::SyntheticSourceOptions src;
  std::filesystem::path cellsDir;
  std::unique_ptr<streaming::CellFileSource> fileSource;
  std::unique_ptr<streaming::SyntheticCellSource> synthetic;
  std::unique_ptr<gpu::Context> ctx;
  std::unique_ptr<streaming::VirRelightSource> virSource;
  streaming::CellSource* source = nullptr;  // what the manager streams from
  std::string sourceText;
};

// Baked cells when --world DIR has DIR/baked/cells (read from DIR/baked/regions when packed), else
// synthetic cells; --relight vir wraps either.
void openCellSources(const FlyOptions& opt, FlySources& cs) {
  streaming::SyntheticSourceOptions& src = cs.src;
  src.layout = {{0.0f, 0.0f}, 64.0f, {64, 64}};
  cs.cellsDir = std::filesystem::path(opt.world) / "baked" / "cells";
  const bool url = streaming::isHttpUrl(opt.world);
  if (!opt.world.empty() && (url || std::filesystem::is_directory(cs.cellsDir))) {
    streaming::CellFileSourceOptions fso;
    if (url)
      fso.worldUrl = opt.world;
    else
      fso.worldDir = opt.world;
    fso.decoder = streaming::parseDecoderChoice(opt.decoder);
    cs.fileSource = std::make_unique<streaming::CellFileSource>(fso);
    src.layout = cs.fileSource->layout();
  } else if (!opt.world.empty()) {
    worlds::WorldParams params = worlds::readWorldManifest(opt.world);
    int cells = int(std::lround(params.sizeM / params.cellM));
    src.layout = {{0.0f, 0.0f}, float(params.cellM), {cells, cells}};
  }
  src.probeSpacing = std::min(8.0f, src.layout.cellSize);
  src.resolution = opt.resolution;
  src.irradianceResolution = std::max(2, opt.resolution / 2);
  src.loadDelayUs = opt.loadDelayUs;
  if (!cs.fileSource) cs.synthetic = std::make_unique<streaming::SyntheticCellSource>(src);
  streaming::CellSource& inner =
      cs.fileSource ? static_cast<streaming::CellSource&>(*cs.fileSource) : *cs.synthetic;
  if (opt.relight == "vir") {
    if (opt.world.empty())
      fail("--relight vir needs --world DIR or URL (the surfels come from the world's cells)");
    cs.ctx = gpu::createContext();
    streaming::VirRelightOptions vo;
    vo.weather = opt.weatherStart;
    cs.virSource = std::make_unique<streaming::VirRelightSource>(
        inner, *cs.ctx, vo,
        url ? streaming::worldSurfelProvider(cs.fileSource->world())
            : streaming::worldSurfelProvider(opt.world));
  } else if (opt.relight != "codec") {
    fail("--relight '{}': expected codec or vir", opt.relight);
  }
  cs.source = cs.virSource ? static_cast<streaming::CellSource*>(cs.virSource.get()) : &inner;
  cs.sourceText =
      cs.fileSource
          ? fmt::format("{} from {} ({} valid, {} missing, {} corrupt; {} decode at load, --decoder {})",
                        cs.fileSource->store().kind(), cs.fileSource->store().location(),
                        cs.fileSource->validCells(), cs.fileSource->missingCells(),
                        cs.fileSource->corruptCells(), cs.fileSource->selection().backend, opt.decoder)
          : std::string("synthetic analytic cells (raw FP32 probe fields) on the world's cell layout");
  if (cs.virSource) cs.sourceText += "; relight: VIR of the world's surfels on the GPU";
  std::printf("source: %s\n", cs.sourceText.c_str());
}

streaming::FlythroughOptions flythroughOptions(const FlyOptions& opt, bool virRelight) {
  streaming::FlythroughOptions fo;
  fo.path = opt.path;
  fo.speed = opt.speed;
  fo.seconds = opt.seconds;
  fo.fps = opt.fps;
  fo.todStart = opt.todStart;
  fo.todEnd = opt.todEnd;
  fo.weatherStart = opt.weatherStart;
  fo.weatherEnd = opt.weatherEnd;
  fo.streaming.relightOnActivate = virRelight;  // the load's codec lighting is the one to replace
  fo.streaming.ioThreads = opt.ioThreads;
  fo.realtime = opt.realtime;
  fo.streaming.maxInlineLoadsPerFrame = opt.loadsPerFrame;
  fo.streaming.memoryBudgetBytes = size_t(opt.budgetMb * 1024.0 * 1024.0);
  fo.streaming.decodeRadius = opt.decodeRadius;
  fo.streaming.keepRadius = opt.decodeRadius * 1.4f;
  // Relight = CellSource::relightInto, run by the manager (IO pool, or inline with --io-threads 0).
  fo.validate();
  return fo;
}

// summary.json without the cell sizes: the source, the flight's frame-time percentiles and counts, and
// the VIR relight's statistics.
nlohmann::ordered_json summaryJson(const FlyOptions& opt, const FlySources& cs,
                                   const streaming::FlythroughOptions& fo,
                                   const streaming::FlythroughSummary& s, double km2) {
  nlohmann::ordered_json j;
  j["source"] = cs.sourceText;
  j["world_km2"] = km2;
  j["speed_mps"] = opt.speed;
  j["frames"] = s.frames;
  j["interrupted"] = s.interrupted;
  j["frames_missing_gi"] = s.framesMissingGi;
  j["fallback_fraction"] = s.fallbackFraction;
  j["p50_frame_ms"] = s.p50FrameMs;
  j["p95_frame_ms"] = s.p95FrameMs;
  j["p99_frame_ms"] = s.p99FrameMs;
  j["p99_update_ms"] = s.p99UpdateMs;
  j["p99_io_ms"] = s.p99IoMs;
  j["p99_activate_ms"] = s.p99ActivateMs;
  j["p99_relight_ms"] = s.p99RelightMs;
  j["p99_shade_ms"] = s.p99ShadeMs;
  j["p50_io_ms"] = s.p50IoMs;
  j["p95_io_ms"] = s.p95IoMs;
  j["p50_activate_ms"] = s.p50ActivateMs;
  j["p95_activate_ms"] = s.p95ActivateMs;
  j["p50_relight_ms"] = s.p50RelightMs;
  j["p95_relight_ms"] = s.p95RelightMs;
  j["p50_relight_io_ms"] = s.p50RelightIoMs;  // per frame with a completed relight, IO thread (or inline)
  j["p95_relight_io_ms"] = s.p95RelightIoMs;
  j["p50_shade_ms"] = s.p50ShadeMs;
  j["p95_shade_ms"] = s.p95ShadeMs;
  j["peak_bytes_resident"] = s.peakBytesResident;
  j["memory_budget_bytes"] = fo.streaming.memoryBudgetBytes;
  j["cells_requested"] = s.cellsRequested;
  j["cells_evicted"] = s.cellsEvicted;
  j["cells_relit"] = s.cellsRelit;
  j["cells_failed"] = s.cellsFailed;
  j["peak_rss_mb"] = peakRssMb();
  j["relight"] = opt.relight;
  j["weather_start"] = opt.weatherStart;
  j["weather_end"] = opt.weatherEnd;
  if (cs.virSource) {
    const streaming::VirRelightStats vs = cs.virSource->stats();
    j["vir_relights"] = vs.relights;
    j["vir_relights_seeded"] = vs.seeded;
    j["vir_relight_ms_mean"] = vs.relights ? vs.relightMsTotal / double(vs.relights) : 0.0;
    j["vir_gpu_ms_mean"] = vs.relights ? vs.gpuMsTotal / double(vs.relights) : 0.0;
    j["vir_surfel_provider_ms_total"] = vs.providerMsTotal;
    j["vir_surfel_cache_bytes"] = vs.cacheBytes;
    j["vir_record_bytes"] = vs.recordBytes;
  }
  return j;
}

// Sizes the memory regression tests pin (tests/baselines/memory.json).
void addCellSizes(nlohmann::ordered_json& j, const FlySources& cs, const streaming::FlythroughOptions& fo) {
  const streaming::SyntheticSourceOptions& src = cs.src;
  const size_t cellBytes = cs.source->maxCellBytes();
  size_t cellProbes = size_t(src.layout.cellSize / src.probeSpacing) *
                      size_t(src.layout.cellSize / src.probeSpacing) * size_t(src.layers);
  if (cs.fileSource) {  // the largest cell's (the slot size)
    for (int z = 0; z < src.layout.cells.y; ++z)
      for (int x = 0; x < src.layout.cells.x; ++x)
        if (const auto& inf = cs.fileSource->info({x, z}); inf.fieldBytes == cellBytes)
          cellProbes = size_t(inf.probes);
    j["cell_files"] = {{"dir", cs.fileSource->store().location()},
                       {"storage", cs.fileSource->store().kind()},
                       {"valid", cs.fileSource->validCells()},
                       {"missing", cs.fileSource->missingCells()},
                       {"corrupt", cs.fileSource->corruptCells()}};
    j["cell_loads"] = cs.fileSource->loads();
    j["cell_read_ms_total"] = cs.fileSource->readMsTotal();
    j["cell_decode_ms_total"] = cs.fileSource->decodeMsTotal();
    j["decoder"] = decoderJson(*cs.fileSource);
    // Decoded bytes of the largest cell of each kind (tests/baselines/memory_baked.json).
    const worlds::SyntheticWorld world(cs.fileSource->world());
    for (int z = 0; z < src.layout.cells.y; ++z)
      for (int x = 0; x < src.layout.cells.x; ++x) {
        const std::string key = fmt::format("field_bytes_{}", worlds::cellKindName(world.cellKind({x, z})));
        const size_t b = cs.fileSource->info({x, z}).fieldBytes;
        if (!j.contains(key) || j[key].get<size_t>() < b) j[key] = b;
      }
  }
  j["cell_bytes"] = cellBytes;
  j["bytes_per_probe"] = double(cellBytes) / double(cellProbes);
  j["pool_bytes"] = (fo.streaming.memoryBudgetBytes / cellBytes) * cellBytes;
}

// gnuplot writes the chart under a temporary name (file_util.h): a failed or killed run never leaves a
// partial profile.png. Returns whether the chart was written.
bool writeProfileChart(const FlyOptions& opt, const std::filesystem::path& out,
                       const streaming::FlythroughOptions& fo, bool render) {
  bool charts = false;
  try {
    writeViaTempFile(out / "profile.png", [&](const std::filesystem::path& tmp) {
      const std::string cmd = fmt::format(
          "gnuplot -e \"dir='{}'; png='{}'; title='{} m/s, {} s'; budget_mb={}; activate_budget_ms={}; "
          "rows={}\" - 2>&1",
          out.string(), tmp.string(), opt.speed, opt.seconds, opt.budgetMb, fo.streaming.activateBudgetMs,
          render ? 4 : 3);
      FILE* gp = popen(cmd.c_str(), "w");
      if (!gp) fail("gnuplot: cannot start");
      std::fputs(kProfileGnuplot, gp);
      if (render) std::fputs(kRenderGnuplot, gp);
      std::fputs("unset multiplot\n", gp);
      if (pclose(gp) != 0) fail("gnuplot failed");
    });
    charts = true;
  } catch (const Error&) {
  }
  return charts;
}

// summary.html's rendered-flight section (empty without --render).
std::string renderHtml(const nlohmann::ordered_json& j) {
  if (!j.contains("render") || j["render"]["frames"].get<size_t>() == 0) return "";
  const nlohmann::ordered_json& r = j["render"];
  const std::string video = r["video"].get<std::string>();
  return fmt::format(
      "<h2>Rendered flight: {} frames at {}x{} on {}</h2>\n<img src='{}'>\n<p>{}; frames in "
      "<code>frames/</code>. GPU ms p50 / p99: G-buffer {:.2f} / {:.2f}, probe shading {:.2f} / {:.2f} "
      "({:.2f} ms per megapixel, {:.2f} x the G-buffer); {} surface pixels missing GI.</p>\n",
      r["frames"].get<size_t>(), r["width"].get<int>(), r["height"].get<int>(),
      r["device"].get<std::string>(), r["strip"].get<std::string>(),
      video.empty() ? r["video_note"].get<std::string>() : fmt::format("<a href='{0}'>{0}</a>", video),
      r["gpu_gbuffer_ms_p50"].get<double>(), r["gpu_gbuffer_ms_p99"].get<double>(),
      r["gpu_shade_ms_p50"].get<double>(), r["gpu_shade_ms_p99"].get<double>(),
      r["shade_ms_per_mpixel"].get<double>(), r["shade_to_gbuffer_ratio_p50"].get<double>(),
      r["pixels_missing_gi"].get<long>());
}

// `lfgi profile`: trace.json, profile.png and summary.html beside frames.csv + summary.json.
void writeProfile(const FlyOptions& opt, const std::filesystem::path& out, const TraceWriter& trace,
                  const streaming::FlythroughOptions& fo, const streaming::FlythroughSummary& s, double km2,
                  const nlohmann::ordered_json& j) {
  trace.save(out / "trace.json");
  const bool charts =
      writeProfileChart(opt, out, fo, j.contains("render") && j["render"]["frames"].get<size_t>() > 0);
  if (!charts) spdlog::warn("gnuplot failed or is missing: no profile.png (install gnuplot-nox)");
  std::string html = fmt::format(
      "<!doctype html><meta charset=utf-8><title>lfgi streaming profile</title>\n"
      "<h1>Streaming profile: {} m/s for {} s over {:.1f} km&sup2;</h1>\n"
      "<p>Open <code>trace.json</code> in <a href='https://ui.perfetto.dev'>Perfetto</a> for every stage "
      "of every frame.</p>\n"
      "<table border=1 cellpadding=4>\n"
      "<tr><td>frames</td><td>{}</td></tr><tr><td>frames with a visible point lacking "
      "GI</td><td>{}</td></tr>\n"
      "<tr><td>fallback fraction of visible samples</td><td>{:.3f} %</td></tr>\n"
      "<tr><td>frame ms p50 / p95 / p99</td><td>{:.3f} / {:.3f} / {:.3f}</td></tr>\n"
      "<tr><td>p99 ms: IO / activate / relight / shade</td><td>{:.3f} / {:.3f} / {:.3f} / "
      "{:.3f}</td></tr>\n"
      "<tr><td>peak resident / budget</td><td>{:.1f} MB / {:.1f} MB</td></tr>\n"
      "<tr><td>cells loaded / evicted / relit / failed</td><td>{} / {} / {} / {}</td></tr>\n"
      "<tr><td>peak RSS</td><td>{:.1f} MB</td></tr></table>\n"
      "<p>Cells: {}</p>\n{}<img src='profile.png' width=1100>\n",
      opt.speed, opt.seconds, km2, s.frames, s.framesMissingGi, 100.0 * s.fallbackFraction, s.p50FrameMs,
      s.p95FrameMs, s.p99FrameMs, s.p99IoMs, s.p99ActivateMs, s.p99RelightMs, s.p99ShadeMs,
      double(s.peakBytesResident) / 1e6, double(fo.streaming.memoryBudgetBytes) / 1e6, s.cellsRequested,
      s.cellsEvicted, s.cellsRelit, s.cellsFailed, peakRssMb(), j["source"].get<std::string>(),
      renderHtml(j));
  writeFileAtomic(out / "summary.html", html);
  std::printf("profile: %s (trace.json for Perfetto, profile.png, summary.html)\n", out.string().c_str());
}

}  // namespace

// --render: the frame renderer over the baked cells (null without --render).
std::unique_ptr<FlyRenderer> makeRenderer(const FlyOptions& opt, const FlySources& cs,
                                          const streaming::FlythroughOptions& fo,
                                          const std::filesystem::path& out, TraceWriter* trace) {
  if (opt.render.empty()) return nullptr;
  if (!cs.fileSource)
    fail(
        "--render needs a baked --world (DIR with baked/ or a URL): synthetic cells have no geometry to "
        "draw");
  FlyRenderOptions ro;
  parseRenderSize(opt.render, ro.width, ro.height);
  ro.every = opt.renderEvery;
  ro.shadeDistance = fo.shadeDistance;
  ro.fps = opt.fps;
  ro.plannedFrames = std::max(1, int(std::lround(double(opt.seconds) * opt.fps)));
  ro.referenceFrames = opt.renderReference;
  ro.referenceSpp = opt.renderReferenceSpp;
  ro.outDir = out;
  return std::make_unique<FlyRenderer>(ro, *cs.fileSource, fo.streaming.keepRadius, trace);
}

nlohmann::ordered_json finishRender(FlyRenderer& renderer, const std::filesystem::path& out) {
  nlohmann::ordered_json r = renderer.finish();
  if (r["frames"].get<size_t>() == 0) return r;
  std::printf(
      "render: %zu frames %dx%d on %s, %ld pixels missing GI, GPU shade p50 %.2f ms (%.2f x the G-buffer), "
      "strip %s, video %s\n",
      r["frames"].get<size_t>(), r["width"].get<int>(), r["height"].get<int>(),
      r["device"].get<std::string>().c_str(), r["pixels_missing_gi"].get<long>(),
      r["gpu_shade_ms_p50"].get<double>(), r["shade_to_gbuffer_ratio_p50"].get<double>(),
      (out / r["strip"].get<std::string>()).string().c_str(),
      r["video"].get<std::string>().empty() ? r["video_note"].get<std::string>().c_str()
                                            : (out / r["video"].get<std::string>()).string().c_str());
  for (const auto& f : r["reference"])
    std::printf(
        "render: frame %d (flight frame %d) vs a %d spp path-traced reference: relative RMS total %.4f, "
        "indirect %.4f\n",
        f["frame"].get<int>(), f["flight_frame"].get<int>(), f["spp"].get<int>(),
        f["total_rel_rms"].get<double>(), f["indirect_rel_rms"].get<double>());
  return r;
}

int runFly(const FlyOptions& opt) {
  FlySources sources;
  openCellSources(opt, sources);
  const streaming::SyntheticSourceOptions& src = sources.src;
  streaming::FlythroughOptions fo = flythroughOptions(opt, sources.virSource != nullptr);

  const std::filesystem::path out =
      opt.outDir.empty() ? (opt.profile ? "out/profile" : "out/fly") : opt.outDir;
  std::filesystem::create_directories(out);
  std::vector<streaming::FlythroughFrame> frames;
  frames.reserve(size_t(opt.seconds * opt.fps) + 1);
  TraceWriter trace;
  std::unique_ptr<FlyRenderer> renderer = makeRenderer(opt, sources, fo, out, opt.profile ? &trace : nullptr);
  if (renderer)
    fo.onFrame = [&](const streaming::FlythroughFrame& f, const streaming::StreamingManager& m) {
      renderer->frame(f, m);
    };
  InterruptGuard guard;
  spdlog::info("fly-through: {} x {} cells of {} m, {} m/s, {} s at {} fps, budget {} MB, {} IO threads",
               src.layout.cells.x, src.layout.cells.y, src.layout.cellSize, opt.speed, opt.seconds, opt.fps,
               opt.budgetMb, opt.ioThreads);
  streaming::FlythroughSummary s = streaming::runFlythrough(
      *sources.source, fo, [&](const streaming::FlythroughFrame& f) { frames.push_back(f); },
      opt.profile ? &trace : nullptr);

  const double km2 =
      double(src.layout.cells.x) * src.layout.cells.y * src.layout.cellSize * src.layout.cellSize / 1e6;
  nlohmann::ordered_json j = summaryJson(opt, sources, fo, s, km2);
  addCellSizes(j, sources, fo);
  if (renderer) {
    j["render"] = finishRender(*renderer, out);
    for (const char* key : {"gpu_shade_ms_p50", "gpu_shade_ms_p99", "shade_ms_per_mpixel"})
      if (j["render"].contains(key)) j[key] = j["render"][key];  // also at the top, as the profile contract
    j["render_device_bytes_peak"] = j["render"].value("device_bytes_peak", size_t(0));
  }
  writeFileAtomic(out / "frames.csv", framesCsv(frames));
  writeFileAtomic(out / "summary.json", j.dump(2) + "\n");
  std::printf(
      "fly-through: %d frames, %d with missing GI, fallback %.2f %% of visible samples, p99 frame %.3f ms, "
      "peak resident %.1f MB, %ld cells loaded\n",
      s.frames, s.framesMissingGi, 100.0 * s.fallbackFraction, s.p99FrameMs,
      double(s.peakBytesResident) / 1e6, s.cellsRequested);
  if (opt.profile) writeProfile(opt, out, trace, fo, s, km2, j);
  if (sources.fileSource) {
    const auto& d = j["decoder"];
    std::printf("decoder: %s (%s), %zu generator decodes, p50 / p95 %.1f / %.1f ms, %.0f probes/s\n",
                d["backend"].get<std::string>().c_str(), d["reason"].get<std::string>().c_str(),
                d["generator_decodes"].get<size_t>(), d["p50_generator_decode_ms"].get<double>(),
                d["p95_generator_decode_ms"].get<double>(), d["generator_decode_probes_per_s"].get<double>());
  }
  std::printf("wrote %s\n", (out / "summary.json").string().c_str());
  return s.interrupted ? 130 : 0;
}

}  // namespace lfgi::app
