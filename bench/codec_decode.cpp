// Benchmark `codec_decode`: decode speed of the generator network (core/generator.h) per probe, for the CPU
// reference (plain loops), the fast CPU decoder (OpenBLAS sgemm + col2im, core/generator_cpu.h) and each GPU
// kernel (gpu/generator_pass.h: barrier-free rowstrip, shared-memory tiled), for several model sizes and batch
// sizes, as GFLOP/s and as a fraction of the same device's GEMM ceiling measured in this run (OpenBLAS sgemm
// for the CPU, shaders/gemm_rowstrip.comp for the Vulkan device: bench/gemm_ceiling.h, as `ceilings` does).
// Accuracy: every row records its max error against the reference decoder on the same probes.
// Weights are random (He init): decode cost does not depend on their values.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <string>
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

template <typename F>
double bestSeconds(int reps, F f) {
  double best = 1e30;
  for (int r = 0; r < reps; ++r) {
    auto t0 = Clock::now();
    f();
    best = std::min(best, std::chrono::duration<double>(Clock::now() - t0).count());
  }
  return best;
}

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
    bench::BenchOutput o(out, quick);
    auto ctx = gpu::createContext();
    o.setDevice(ctx->info.name);
    spdlog::info("codec_decode on {} ({})", ctx->info.name, quick ? "quick" : "full");

    // Ceilings of the same devices, in this run. The machine may be shared, so each row's fraction uses a
    // ceiling re-measured just before that row, defined as bench/ceilings does (best over GEMM sizes; here
    // 256^3 and 512^3 for the GPU, 512^3 for OpenBLAS); the summary keeps the best ceilings seen.
    gpu::Program gemmProgram(*ctx, "gemm_rowstrip");
    double gemmCeiling = 0.0, sgemmCeiling = 0.0;
    auto gpuCeilingNow = [&] {
      double best = 0.0;
      for (int size : {256, 512}) {
        bench::GemmResult g = bench::gpuGemm(*ctx, gemmProgram, size);
        if (g.maxRelError > 1e-4) fail("GPU GEMM {}^3 disagrees with OpenBLAS (max rel error {:.2e})", size, g.maxRelError);
        best = std::max(best, g.gflops);
      }
      gemmCeiling = std::max(gemmCeiling, best);
      return best;
    };
    auto cpuCeilingNow = [&] {
      double g = bench::cpuSgemmGflops(512);
      sgemmCeiling = std::max(sgemmCeiling, g);
      return g;
    };
    spdlog::info("ceilings now: GPU gemm_rowstrip {:.2f} GFLOP/s, CPU OpenBLAS sgemm 512^3 {:.1f} GFLOP/s",
                 gpuCeilingNow(), cpuCeilingNow());

    o.setColumns({"model", "out_res", "mflop_per_probe", "method", "batch_probes", "decode_us_per_probe",
                  "probes_per_s", "gflops", "fraction_of_ceiling", "ceiling_gflops", "max_rel_error_vs_reference"});
    const std::vector<uint32_t> batches = quick ? std::vector<uint32_t>{64, 256} : std::vector<uint32_t>{64, 256, 1024};
    const uint32_t refProbes = 16;  // the reference decoder runs on this many probes (it is slow)
    gpu::GeneratorDecodePass pass(*ctx);
    auto condArr = conditioningVector(13.0f, 0.2f);
    std::vector<float> cond(condArr.begin(), condArr.end());
    nlohmann::ordered_json perModel = nlohmann::ordered_json::object();
    double headlineGpuPps = 0, headlineGpuFrac = 0, headlineCpuPps = 0, headlineCpuFrac = 0;
    std::string headlineGpuKernel;

    unsigned seed = 1;
    for (const bench::Model& m : bench::models()) {
      const GeneratorArch& a = m.arch;
      const double flop = 2.0 * a.macsPerProbe();
      const size_t R = size_t(a.outputResolution()), per = size_t(a.outChannels()) * R * R;
      GeneratorWeights w = randomGeneratorWeights(a, seed++);
      const uint32_t maxBatch = batches.back();
      std::vector<float> z(size_t(maxBatch) * size_t(a.latentDim));
      std::mt19937 rng(seed++);
      std::normal_distribution<float> nd(0.0f, 1.0f);
      for (float& v : z) v = nd(rng);

      std::vector<float> ref(refProbes * per);
      const double refS = bench::bestSeconds(1, [&] { generatorForward(w, std::span(z).first(refProbes * size_t(a.latentDim)), cond, refProbes, ref); });
      auto addRow = [&](const std::string& method, uint32_t batch, double seconds, double ceiling, double err) {
        const double us = seconds / batch * 1e6, gflops = flop * batch / seconds * 1e-9;
        o.addRow({m.name, std::to_string(R), bench::num(flop * 1e-6), method, std::to_string(batch), bench::num(us),
                  bench::num(batch / seconds), bench::num(gflops), bench::num(gflops / ceiling), bench::num(ceiling),
                  bench::num(err)});
        spdlog::info("{:12} {:18} batch {:5}: {:9.2f} us/probe  {:7.2f} GFLOP/s  {:5.1f} % of ceiling  err {:.1e}",
                     m.name, method, batch, us, gflops, 100.0 * gflops / ceiling, err);
        return gflops / ceiling;
      };
      addRow("cpu_reference", refProbes, refS, cpuCeilingNow(), 0.0);

      GeneratorCpu fast(w);
      gpu::GeneratorGpuModel gm(*ctx, w);
      nlohmann::ordered_json mj;
      mj["mflop_per_probe"] = flop * 1e-6;
      mj["parameters"] = a.parameterCount();
      for (uint32_t batch : batches) {
        std::span<const float> zb = std::span(z).first(size_t(batch) * size_t(a.latentDim));
        std::vector<float> y(size_t(batch) * per);
        const double cpuCeiling = cpuCeilingNow();
        const double cpuS = bench::bestSeconds(3, [&] { fast.forward(zb, cond, batch, y); });
        const double cpuFrac = addRow("cpu_sgemm", batch, cpuS, cpuCeiling,
                                      bench::relMaxError(std::span(y).first(ref.size()), ref));
        mj["cpu_sgemm_batch_" + std::to_string(batch) + "_fraction"] = cpuFrac;

        gpu::Buffer lat = gpu::createStorageBuffer(*ctx, zb.size_bytes());
        gpu::upload<float>(*ctx, lat, zb);
        gpu::Buffer outBuf = gpu::createStorageBuffer(*ctx, y.size() * sizeof(float));
        gpu::GeneratorScratch scratch(*ctx, a, batch);
        for (gpu::GeneratorKernel k : {gpu::GeneratorKernel::RowStrip, gpu::GeneratorKernel::Tiled}) {
          // the tiled kernel is several times slower on lavapipe: one repetition of the large batches only
          const int reps = (k == gpu::GeneratorKernel::Tiled && batch > 64) ? 1 : 3;
          const double gpuCeiling = gpuCeilingNow();
          const double ms = bench::bestGpuMs(*ctx, reps, [&](VkCommandBuffer cmd) {
            pass.record(cmd, gm, scratch, lat, cond, batch, outBuf, k);
          });
          std::vector<float> g(ref.size());
          gpu::readback<float>(*ctx, outBuf, g);
          const std::string method = std::string("gpu_") + gpu::generatorKernelName(k);
          const double frac = addRow(method, batch, ms * 1e-3, gpuCeiling, bench::relMaxError(g, ref));
          mj[method + "_batch_" + std::to_string(batch) + "_fraction"] = frac;
          if (m.name == "medium_16px" && batch == maxBatch && frac > headlineGpuFrac) {
            headlineGpuFrac = frac;
            headlineGpuPps = batch / (ms * 1e-3);
            headlineGpuKernel = gpu::generatorKernelName(k);
          }
        }
        if (m.name == "medium_16px" && batch == maxBatch) {
          headlineCpuPps = batch / cpuS;
          headlineCpuFrac = cpuFrac;
        }
      }
      perModel[m.name] = mj;
    }
    auto& s = o.summary();
    s["gpu_decode_probes_per_s"] = headlineGpuPps;
    s["gpu_decode_fraction_of_gemm_ceiling"] = headlineGpuFrac;
    s["gpu_decode_kernel"] = headlineGpuKernel;
    s["cpu_decode_probes_per_s"] = headlineCpuPps;
    s["cpu_decode_fraction_of_sgemm"] = headlineCpuFrac;
    s["headline_model"] = "medium_16px";
    s["headline_batch_probes"] = batches.back();
    s["gemm_gflops"] = gemmCeiling;
    s["cpu_sgemm_gflops"] = sgemmCeiling;
    s["models"] = perModel;
    o.save();
    spdlog::info("wrote {}", (o.dir() / "summary.json").string());
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
