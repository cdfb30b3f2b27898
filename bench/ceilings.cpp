// Benchmark `ceilings`: the machine's own limits, used as denominators by the other benchmarks
// (docs/DESIGN.md §6): register-only FMA rate and the project's best GEMM kernel on the Vulkan device, 64-bit
// atomicMin rate, device buffer copy bandwidth, OpenBLAS sgemm on all CPU threads and a STREAM-like
// triad. GPU times come from timestamps; each figure is the best of several repetitions.
#include <cblas.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <thread>
#include <vector>

#include "bench/bench_output.h"
#include "bench/gemm_ceiling.h"
#include "core/error.h"
#include "gpu/buffer.h"
#include "gpu/context.h"
#include "gpu/program.h"
#include "gpu/timing.h"
#include "shared/ceilings.h"

extern "C" char* openblas_get_corename();  // OpenBLAS extension: the kernel set in use

namespace lfgi::bench {
namespace {

using Clock = std::chrono::steady_clock;

double fmaGflops(gpu::Context& ctx, bool quick) {
  gpu::Program p(ctx, "fma_peak");
  const uint32_t threads = 1u << 16, iterations = quick ? 2048 : 8192;
  gpu::Buffer out = gpu::createStorageBuffer(ctx, threads * 16);
  shared::FmaParams params{iterations, threads, 0, 0};
  double ms = bestGpuMs(ctx, 3, [&](VkCommandBuffer cmd) {
    gpu::dispatch(ctx, cmd, p, {&out}, params, {threads, 1, 1});
  });
  return double(threads) * iterations * 64.0 / (ms * 1e-3) * 1e-9;
}

double atomicsPerSecond(gpu::Context& ctx, bool quick) {
  if (!ctx.features.shaderBufferInt64Atomics) return 0.0;
  gpu::Program p(ctx, "atomic_min64");
  const uint32_t slots = 1u << 20, threads = 1u << 16, updates = quick ? 16 : 64;
  gpu::Buffer buf = gpu::createStorageBuffer(ctx, size_t(slots) * 8);
  gpu::fillBuffer(ctx, buf, 0xffffffffu);
  shared::AtomicParams params{slots, updates, threads, 7};
  double ms = bestGpuMs(ctx, 3, [&](VkCommandBuffer cmd) {
    gpu::dispatch(ctx, cmd, p, {&buf}, params, {threads, 1, 1});
  });
  return double(threads) * updates / (ms * 1e-3);
}

double copyGbPerSecond(gpu::Context& ctx, bool quick) {
  const VkDeviceSize bytes = (quick ? 64ull : 256ull) << 20;
  gpu::Buffer src = gpu::createStorageBuffer(ctx, bytes), dst = gpu::createStorageBuffer(ctx, bytes);
  gpu::fillBuffer(ctx, src, 1u);
  double ms = bestGpuMs(ctx, 3, [&](VkCommandBuffer cmd) {
    VkBufferCopy region{0, 0, bytes};
    vkCmdCopyBuffer(cmd, src.handle(), dst.handle(), 1, &region);
  });
  return 2.0 * double(bytes) / (ms * 1e-3) * 1e-9;  // read + write, as STREAM counts copy
}

double cpuTriadGbPerSecond(bool quick) {
  const size_t n = quick ? (8u << 20) : (32u << 20);
  std::vector<float> a(n), b(n, 1.0f), c(n, 2.0f);
  const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  double best = 1e30;
  for (int r = 0; r < 5; ++r) {
    auto t0 = Clock::now();
    std::vector<std::thread> pool;
    for (unsigned t = 0; t < threads; ++t)
      pool.emplace_back([&, t] {
        size_t lo = n * t / threads, hi = n * (t + 1) / threads;
        for (size_t i = lo; i < hi; ++i) a[i] = b[i] + 3.0f * c[i];
      });
    for (auto& th : pool) th.join();
    best = std::min(best, std::chrono::duration<double>(Clock::now() - t0).count());
  }
  if (a[n / 2] != 7.0f) fail("triad produced a wrong value");
  return 3.0 * double(n) * sizeof(float) / best * 1e-9;
}

}  // namespace
}  // namespace lfgi::bench

int main(int argc, char** argv) {
  using namespace lfgi;
  CLI::App app{"lfgi benchmark: machine ceilings"};
  std::string out = "out/bench/ceilings";
  bool quick = false;
  app.add_option("--out", out, "Output directory");
  app.add_flag("--quick", quick, "Smaller sizes (< 1 minute)");
  CLI11_PARSE(app, argc, argv);
  try {
    bench::BenchOutput o(out, quick);
    auto ctx = gpu::createContext();
    o.setDevice(ctx->info.name);
    spdlog::info("ceilings on {} ({})", ctx->info.name, quick ? "quick" : "full");

    const double fma = bench::fmaGflops(*ctx, quick);
    spdlog::info("fma: {:.2f} GFLOP/s", fma);
    gpu::Program gemmProgram(*ctx, "gemm_rowstrip");
    o.setColumns({"measure", "size", "value", "unit", "max_rel_error"});
    std::vector<std::vector<std::string>> gemmRows;
    double bestGemm = 0.0;
    for (int size : quick ? std::vector<int>{128, 256, 512} : std::vector<int>{128, 256, 512, 1024}) {
      bench::GemmResult g = bench::gpuGemm(*ctx, gemmProgram, size);
      spdlog::info("gemm {}^3: {:.2f} GFLOP/s, max rel error {:.2e}", size, g.gflops, g.maxRelError);
      gemmRows.push_back(
          {"gemm_rowstrip", std::to_string(size), bench::num(g.gflops), "gflops", bench::num(g.maxRelError)});
      if (g.maxRelError > 1e-4)
        fail("GPU GEMM {}^3 disagrees with OpenBLAS (max rel error {:.2e})", size, g.maxRelError);
      bestGemm = std::max(bestGemm, g.gflops);
    }
    const double atomics = bench::atomicsPerSecond(*ctx, quick);
    spdlog::info("atomicMin64: {:.1f} M/s", atomics * 1e-6);
    const double copy = bench::copyGbPerSecond(*ctx, quick);
    spdlog::info("copy: {:.2f} GB/s", copy);
    const int sgemmSize = quick ? 512 : 1024;
    const double sgemm = bench::cpuSgemmGflops(sgemmSize);
    spdlog::info(
        "OpenBLAS sgemm {}^3: {:.1f} GFLOP/s (kernels: {}; set OPENBLAS_CORETYPE if that is wrong, "
        "scripts/env.sh does)",
        sgemmSize, sgemm, openblas_get_corename());
    const double triad = bench::cpuTriadGbPerSecond(quick);
    spdlog::info("CPU triad: {:.1f} GB/s", triad);

    o.addRow({"fma", "0", bench::num(fma), "gflops", "0"});
    o.addRow({"atomics64", "1048576", bench::num(atomics), "per_s", "0"});
    o.addRow({"copy", "0", bench::num(copy), "gb_per_s", "0"});
    o.addRow({"cpu_sgemm", std::to_string(sgemmSize), bench::num(sgemm), "gflops", "0"});
    o.addRow({"cpu_triad", "0", bench::num(triad), "gb_per_s", "0"});
    for (const auto& row : gemmRows) o.addRow(row);  // after the 5 ceilings: the chart's bars are rows 0..4
    auto& s = o.summary();
    s["fma_gflops"] = fma;
    s["gemm_gflops"] = bestGemm;
    s["cpu_sgemm_gflops"] = sgemm;
    s["atomics64_per_s"] = atomics;
    s["copy_gb_per_s"] = copy;
    s["cpu_triad_gb_per_s"] = triad;
    s["openblas_core"] = openblas_get_corename();
    o.save();
    spdlog::info("wrote {}", (o.dir() / "summary.json").string());
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
