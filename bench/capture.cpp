// Benchmark `capture`: Embree ground-truth probe capture (bake/probe_capture.h) on the 2 cores.
// Probes: active probes of a city cell of the default world (its mesh + its 8 neighbours' meshes), the
// same scene `lfgi capture --world` uses. Sweeps samples per texel at the default resolution (cost vs
// Monte-Carlo noise: the accuracy axis) and resolution at the default sample count.
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <thread>
#include <tuple>

#include "bake/probe_capture.h"
#include "bench/bench_output.h"
#include "core/error.h"
#include "worlds/world_cells.h"

int main(int argc, char** argv) {
  using namespace lfgi;
  CLI::App app{"lfgi benchmark: Embree probe capture"};
  std::string out = "out/bench/capture";
  bool quick = false;
  app.add_option("--out", out, "Output directory");
  app.add_flag("--quick", quick, "Fewer probes and settings");
  CLI11_PARSE(app, argc, argv);
  try {
    bench::BenchOutput o(out, quick);
    o.setDevice(fmt::format("cpu ({} threads, Embree)", std::thread::hardware_concurrency()));
    worlds::SyntheticWorld world(worlds::WorldParams::smallDefault(1));
    const worlds::CellCoord cell{2, 1};  // arcade block of the showcase district
    worlds::BuiltCell built = worlds::buildCell(world, cell);
    worlds::TriangleMesh mesh = built.mesh;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dx = -1; dx <= 1; ++dx)
        if ((dx || dz) && world.contains({cell.x + dx, cell.z + dz}))
          mesh.append(world.generateCell({cell.x + dx, cell.z + dz}));
    bake::EmbreeScene scene(mesh, "capture benchmark scene");
    worlds::SkyState st;
    st.timeOfDayHours = 15.5f;
    const worlds::SkyModel sky = worlds::makeSky(st);

    // Every k-th active probe, so the sample spans the cell's layers and interiors.
    std::vector<glm::vec3> all;
    for (int64_t i = 0; i < built.probes.grid.probeCount(); ++i)
      if (!(built.probes.flags[size_t(i)] & worlds::kProbeDisabledSolid))
        all.push_back(built.probes.position(i));
    const size_t want = quick ? 24 : 96;
    std::vector<glm::vec3> probes;
    for (size_t i = 0; i < all.size() && probes.size() < want; i += std::max<size_t>(1, all.size() / want))
      probes.push_back(all[i]);
    spdlog::info("capture benchmark: {} probes of cell {},{} ({} triangles incl. neighbours)", probes.size(),
                 cell.x, cell.z, mesh.triangleCount());

    o.setColumns({"sweep", "resolution", "samples_per_texel", "probes", "seconds", "ms_per_probe",
                  "rays_per_s", "mean_rel_std_error"});
    auto run = [&](const char* sweep, int res, int spp) {
      bake::CaptureOptions opt;
      opt.resolution = res;
      opt.samplesPerTexel = spp;
      bake::CaptureResult r = bake::captureProbes(scene, sky, probes, opt);
      double err = 0.0;
      for (const auto& p : r.probes) err += p.meanRelativeStdError;
      err /= double(r.probes.size());
      const double msPerProbe = r.seconds * 1e3 / double(r.probesDone);
      spdlog::info("{} {}x{} {} spp: {:.1f} ms/probe, {:.2f} M rays/s, mean rel std error {:.2f} %", sweep,
                   res, res, spp, msPerProbe, r.raysPerSecond() * 1e-6, 100.0 * err);
      o.addRow({sweep, std::to_string(res), std::to_string(spp), std::to_string(r.probesDone),
                bench::num(r.seconds), bench::num(msPerProbe), bench::num(r.raysPerSecond()),
                bench::num(err)});
      return std::make_tuple(msPerProbe, r.raysPerSecond(), err);
    };
    double ms = 0.0, rays = 0.0, err = 0.0;  // headline: the defaults (16x16 maps, 64 samples per texel)
    for (int spp : quick ? std::vector<int>{16, 64} : std::vector<int>{16, 64, 256}) {
      auto r = run("spp", 16, spp);
      if (spp == 64) std::tie(ms, rays, err) = r;
    }
    for (int res : quick ? std::vector<int>{8, 16} : std::vector<int>{8, 16, 32}) run("resolution", res, 64);
    auto& s = o.summary();
    s["capture_rays_per_s"] = rays;
    s["capture_ms_per_probe"] = ms;
    s["capture_mean_rel_std_error"] = err;
    s["resolution"] = 16;
    s["samples_per_texel"] = 64;
    s["probes"] = probes.size();
    o.save();
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
