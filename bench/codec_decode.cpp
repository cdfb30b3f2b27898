// Benchmark `codec_decode`: decode speed of the generator network (core/generator.h) per probe, for the CPU
// reference (plain loops), the fast CPU decoder (OpenBLAS sgemm + col2im, core/generator_cpu.h) and each GPU
// kernel (gpu/generator_pass.h: barrier-free rowstrip, shared-memory tiled), for several model sizes and
// batch sizes, as GFLOP/s and as a fraction of the same device's GEMM ceiling measured in this run (OpenBLAS
// sgemm for the CPU, shaders/gemm_rowstrip.comp for the Vulkan device: bench/gemm_ceiling.h, as `ceilings`
// does). Accuracy: every row records its max error against the reference decoder on the same probes. Weights
// are random (He init): decode cost does not depend on their values.
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "bench/bench_output.h"
#include "bench/gemm_ceiling.h"
#include "core/error.h"
#include "core/generator.h"
#include "core/generator_cpu.h"
#include "gpu/buffer.h"
#include "gpu/context.h"
#include "gpu/generator_pass.h"

namespace lfgi::bench {
namespace {

using Clock = std::chrono::steady_clock;

struct Model {
  std::string name;
  GeneratorArch arch;
};

std::vector<Model> models() {
  auto make = [](std::string name, std::vector<int> channels) {
    GeneratorArch a;
    a.latentDim = 16;
    a.condDim = kConditioningDim;
    a.convChannels = std::move(channels);
    return Model{std::move(name), a};
  };
  return {make("small_16px", {32, 16, kGeneratorChannels}), make("medium_16px", {64, 32, kGeneratorChannels}),
          make("large_32px", {128, 64, 32, kGeneratorChannels})};
}

double relMaxError(std::span<const float> a, std::span<const float> ref) {
  double scale = 0.0, err = 0.0;
  for (size_t i = 0; i < ref.size(); ++i) {
    scale = std::max(scale, double(std::abs(ref[i])));
    err = std::max(err, double(std::abs(a[i] - ref[i])));
  }
  return err / std::max(scale, 1e-30);
}

// Best wall-clock and best process-CPU seconds of `reps` calls.
struct Seconds {
  double wall = 1e30, cpu = 1e30;
};
template <typename F>
Seconds bestSeconds(int reps, F f) {
  Seconds best;
  for (int r = 0; r < reps; ++r) {
    auto t0 = Clock::now();
    const double c0 = processCpuSeconds();
    f();
    best.cpu = std::min(best.cpu, processCpuSeconds() - c0);
    best.wall = std::min(best.wall, std::chrono::duration<double>(Clock::now() - t0).count());
  }
  return best;
}

struct Ceiling {
  double wall = 0.0, cpu = 0.0;  // GFLOP per second of wall / of process CPU time
};

struct Headline {
  double pps = 0, frac = 0, fracWall = 0, fracCpu = 0;
  std::string kernel;
};

// Ceilings of the same devices, in this run, defined as bench/ceilings does (best over GEMM sizes; here
// 256^3 and 512^3 for the GPU, 512^3 for OpenBLAS), re-measured just before each row. Two bases: device
// (wall) time, the contract on a real GPU; and process CPU time, which on lavapipe (a CPU device) is the
// work itself and stays meaningful when other processes share the cores (a 7 ms GEMM often gets both
// cores while a 300 ms decode gets its fair share, which makes wall-time ratios of a loaded machine
// noise).
class DecodeBench {
 public:
  DecodeBench(const std::string& out, bool quick)
      : o_(out, quick),
        ctx_(gpu::createContext()),
        cpuDevice_(ctx_->info.type == "cpu"),
        gemmProgram_(*ctx_, "gemm_rowstrip"),
        pass_(*ctx_),
        batches_(quick ? std::vector<uint32_t>{64, 256} : std::vector<uint32_t>{64, 256, 1024}) {
    o_.setDevice(ctx_->info.name);
    spdlog::info("codec_decode on {} ({})", ctx_->info.name, quick ? "quick" : "full");
    const auto condArr = conditioningVector(13.0f, 0.2f);
    cond_.assign(condArr.begin(), condArr.end());
  }

  void run() {
    const Ceiling g = gpuCeilingNow(), c = cpuCeilingNow();
    spdlog::info(
        "ceilings now: GPU gemm_rowstrip {:.2f} GFLOP/s ({:.2f} per CPU-s), OpenBLAS sgemm 512^3 {:.1f} "
        "GFLOP/s ({:.1f} per CPU-s)",
        g.wall, g.cpu, c.wall, c.cpu);
    o_.setColumns({"model", "out_res", "mflop_per_probe", "method", "batch_probes", "decode_us_per_probe",
                   "probes_per_s", "gflops", "fraction_of_ceiling", "ceiling_gflops", "gflops_per_cpu_s",
                   "fraction_of_ceiling_cpu_time", "ceiling_gflops_per_cpu_s", "max_rel_error_vs_reference"});
    nlohmann::ordered_json perModel = nlohmann::ordered_json::object();
    unsigned seed = 1;
    for (const Model& m : models()) perModel[m.name] = measureModel(m, seed);
    writeSummary(perModel);
    o_.save();
    spdlog::info("wrote {}", (o_.dir() / "summary.json").string());
  }

 private:
  static constexpr uint32_t kRefProbes = 16;  // the reference decoder runs on this many probes (it is slow)

  Ceiling gpuCeilingNow() {
    Ceiling c;
    for (int size : {256, 512}) {
      GemmResult g = gpuGemm(*ctx_, gemmProgram_, size);
      if (g.maxRelError > 1e-4)
        fail("GPU GEMM {}^3 disagrees with OpenBLAS (max rel error {:.2e})", size, g.maxRelError);
      c.wall = std::max(c.wall, g.gflops);
      c.cpu = std::max(c.cpu, g.gflopsPerCpuSecond);
    }
    gemmCeiling_ = std::max(gemmCeiling_, c.wall);
    return c;
  }
  Ceiling cpuCeilingNow() {
    GemmResult g = cpuSgemm(512);
    sgemmCeiling_ = std::max(sgemmCeiling_, g.gflops);
    return Ceiling{g.gflops, g.gflopsPerCpuSecond};
  }

  // One CSV row; returns {fraction (wall), fraction (CPU time)}.
  std::pair<double, double> addRow(const Model& m, const std::string& method, uint32_t batch, Seconds t,
                                   Ceiling ceil, double err) {
    const GeneratorArch& a = m.arch;
    const double flop = 2.0 * a.macsPerProbe();
    const size_t R = size_t(a.outputResolution());
    const double us = t.wall / batch * 1e6, gflops = flop * batch / t.wall * 1e-9;
    const double gflopsCpu = flop * batch / t.cpu * 1e-9;
    o_.addRow({m.name, std::to_string(R), num(flop * 1e-6), method, std::to_string(batch), num(us),
               num(batch / t.wall), num(gflops), num(gflops / ceil.wall), num(ceil.wall), num(gflopsCpu),
               num(gflopsCpu / ceil.cpu), num(ceil.cpu), num(err)});
    spdlog::info(
        "{:12} {:13} batch {:5}: {:9.2f} us/probe {:6.2f} GFLOP/s = {:5.1f} % of ceiling; per CPU-s "
        "{:6.2f} = {:5.1f} %; err {:.1e}",
        m.name, method, batch, us, gflops, 100.0 * gflops / ceil.wall, gflopsCpu,
        100.0 * gflopsCpu / ceil.cpu, err);
    return std::pair{gflops / ceil.wall, gflopsCpu / ceil.cpu};
  }

  // The reference decode, then per batch the CPU sgemm decoder and each GPU kernel; the model's summary.
  nlohmann::ordered_json measureModel(const Model& m, unsigned& seed) {
    const GeneratorArch& a = m.arch;
    const size_t R = size_t(a.outputResolution()), per = size_t(a.outChannels()) * R * R;
    const GeneratorWeights w = randomGeneratorWeights(a, seed++);
    const uint32_t maxBatch = batches_.back();
    std::vector<float> z(size_t(maxBatch) * size_t(a.latentDim));
    std::mt19937 rng(seed++);
    std::normal_distribution<float> nd(0.0f, 1.0f);
    for (float& v : z) v = nd(rng);

    std::vector<float> ref(kRefProbes * per);
    {
      const Ceiling c = cpuCeilingNow();
      const Seconds t = bestSeconds(1, [&] {
        generatorForward(w, std::span(z).first(kRefProbes * size_t(a.latentDim)), cond_, kRefProbes, ref);
      });
      addRow(m, "cpu_reference", kRefProbes, t, c, 0.0);
    }
    GeneratorCpu fast(w);
    gpu::GeneratorGpuModel gm(*ctx_, w);
    nlohmann::ordered_json mj;
    mj["mflop_per_probe"] = 2.0 * a.macsPerProbe() * 1e-6;
    mj["parameters"] = a.parameterCount();
    for (uint32_t batch : batches_) {
      std::span<const float> zb = std::span(z).first(size_t(batch) * size_t(a.latentDim));
      std::vector<float> y(size_t(batch) * per);
      const Ceiling cpuCeiling = cpuCeilingNow();
      const Seconds cpuT = bestSeconds(3, [&] { fast.forward(zb, cond_, batch, y); });
      auto [cpuWall, cpuCpu] =
          addRow(m, "cpu_sgemm", batch, cpuT, cpuCeiling, relMaxError(std::span(y).first(ref.size()), ref));
      mj["cpu_sgemm_batch_" + std::to_string(batch) + "_fraction"] = cpuWall;
      measureGpuKernels(m, gm, zb, batch, y.size(), ref, mj);
      if (m.name == "medium_16px" && batch == maxBatch)
        hc_ = {batch / cpuT.wall, cpuCpu, cpuWall, cpuCpu, "sgemm"};
    }
    return mj;
  }

  void measureGpuKernels(const Model& m, const gpu::GeneratorGpuModel& gm, std::span<const float> zb,
                         uint32_t batch, size_t outFloats, const std::vector<float>& ref,
                         nlohmann::ordered_json& mj) {
    gpu::Buffer lat = gpu::createStorageBuffer(*ctx_, zb.size_bytes());
    gpu::upload<float>(*ctx_, lat, zb);
    gpu::Buffer outBuf = gpu::createStorageBuffer(*ctx_, outFloats * sizeof(float));
    gpu::GeneratorScratch scratch(*ctx_, m.arch, batch);
    for (gpu::GeneratorKernel k : {gpu::GeneratorKernel::RowStrip, gpu::GeneratorKernel::Tiled}) {
      // the tiled kernel is several times slower on lavapipe: one repetition of the large batches only
      const int reps = (k == gpu::GeneratorKernel::Tiled && batch > 64) ? 1 : 3;
      const Ceiling gpuCeiling = gpuCeilingNow();
      const GpuTime t = bestGpuTime(*ctx_, reps, [&](VkCommandBuffer cmd) {
        pass_.record(cmd, gm, scratch, lat, cond_, batch, outBuf, k);
      });
      std::vector<float> g(ref.size());
      gpu::readback<float>(*ctx_, outBuf, g);
      const std::string method = std::string("gpu_") + gpu::generatorKernelName(k);
      auto [wall, cpu] =
          addRow(m, method, batch, {t.ms * 1e-3, t.cpuMs * 1e-3}, gpuCeiling, relMaxError(g, ref));
      mj[method + "_batch_" + std::to_string(batch) + "_fraction"] = wall;
      if (cpuDevice_) mj[method + "_batch_" + std::to_string(batch) + "_fraction_cpu_time"] = cpu;
      const double headline = cpuDevice_ ? cpu : wall;
      if (m.name == "medium_16px" && batch == batches_.back() && headline > hg_.frac)
        hg_ = {batch / (t.ms * 1e-3), headline, wall, cpu, gpu::generatorKernelName(k)};
    }
  }

  void writeSummary(const nlohmann::ordered_json& perModel) {
    auto& s = o_.summary();
    s["gpu_decode_probes_per_s"] = hg_.pps;
    s["gpu_decode_fraction_of_gemm_ceiling"] = hg_.frac;
    s["gpu_decode_fraction_basis"] = cpuDevice_ ? "process CPU time (CPU device)" : "device time";
    s["gpu_decode_fraction_of_gemm_ceiling_device_time"] = hg_.fracWall;
    s["gpu_decode_kernel"] = hg_.kernel;
    s["cpu_decode_probes_per_s"] = hc_.pps;
    s["cpu_decode_fraction_of_sgemm"] = hc_.frac;
    s["cpu_decode_fraction_basis"] = "process CPU time";
    s["cpu_decode_fraction_of_sgemm_wall_time"] = hc_.fracWall;
    s["headline_model"] = "medium_16px";
    s["headline_batch_probes"] = batches_.back();
    s["gemm_gflops"] = gemmCeiling_;
    s["cpu_sgemm_gflops"] = sgemmCeiling_;
    s["models"] = perModel;
  }

  BenchOutput o_;
  std::unique_ptr<gpu::Context> ctx_;
  bool cpuDevice_;
  gpu::Program gemmProgram_;
  gpu::GeneratorDecodePass pass_;
  std::vector<uint32_t> batches_;
  std::vector<float> cond_;
  double gemmCeiling_ = 0.0, sgemmCeiling_ = 0.0;
  Headline hg_, hc_;
};

}  // namespace
}  // namespace lfgi::bench

int main(int argc, char** argv) {
  using namespace lfgi;
  CLI::App app{"lfgi benchmark: generator decode speed (CPU reference, CPU sgemm, GPU kernels)"};
  std::string out = "out/bench/codec_decode";
  bool quick = false;
  app.add_option("--out", out, "Output directory");
  app.add_flag("--quick", quick, "Smaller batches (< 10 minutes on 2 cores)");
  CLI11_PARSE(app, argc, argv);
  try {
    bench::DecodeBench(out, quick).run();
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
