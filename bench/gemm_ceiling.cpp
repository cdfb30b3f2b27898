#include "bench/gemm_ceiling.h"

#include <cblas.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <random>
#include <vector>

#include "gpu/buffer.h"
#include "gpu/timing.h"
#include "shared/ceilings.h"

namespace lfgi::bench {

double processCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

GpuTime bestGpuTime(gpu::Context& ctx, int reps, const std::function<void(VkCommandBuffer)>& record) {
  gpu::GpuTimer timer(ctx, 2);
  GpuTime best{1e30, 1e30};
  for (int r = 0; r < reps; ++r) {
    const double cpu0 = processCpuSeconds();
    gpu::submitAndWait(ctx, [&](VkCommandBuffer cmd) {
      timer.reset(cmd);
      timer.stamp(cmd, 0);
      record(cmd);
      timer.stamp(cmd, 1);
    });
    best.cpuMs = std::min(best.cpuMs, (processCpuSeconds() - cpu0) * 1e3);
    best.ms = std::min(best.ms, timer.elapsedMs(0, 1));
  }
  return best;
}

double bestGpuMs(gpu::Context& ctx, int reps, const std::function<void(VkCommandBuffer)>& record) {
  return bestGpuTime(ctx, reps, record).ms;
}

GemmResult gpuGemm(gpu::Context& ctx, gpu::Program& p, int size) {
  const int m = size, n = size, k = size;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> a(size_t(m) * k), b(size_t(k) * n), c(size_t(m) * n), ref(size_t(m) * n);
  for (float& v : a) v = u(rng);
  for (float& v : b) v = u(rng);
  gpu::Buffer ba = gpu::createStorageBuffer(ctx, a.size() * 4),
              bb = gpu::createStorageBuffer(ctx, b.size() * 4),
              bc = gpu::createStorageBuffer(ctx, c.size() * 4);
  gpu::upload<float>(ctx, ba, a);
  gpu::upload<float>(ctx, bb, b);
  shared::GemmParams params{uint32_t(m), uint32_t(n), uint32_t(k), 0};
  const uint32_t threads = uint32_t(m / 4) * uint32_t(n / 4);
  GpuTime t = bestGpuTime(ctx, 3, [&](VkCommandBuffer cmd) {
    gpu::dispatch(ctx, cmd, p, {&ba, &bb, &bc}, params, {threads, 1, 1});
  });
  gpu::readback<float>(ctx, bc, c);
  cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, m, n, k, 1.0f, a.data(), k, b.data(), n, 0.0f,
              ref.data(), n);
  GemmResult r;
  double scale = 0.0;
  for (float v : ref) scale = std::max(scale, double(std::abs(v)));
  for (size_t i = 0; i < c.size(); ++i)
    r.maxRelError = std::max(r.maxRelError, std::abs(double(c[i]) - ref[i]) / scale);
  r.gflops = 2.0 * m * n * k / (t.ms * 1e-3) * 1e-9;
  r.gflopsPerCpuSecond = 2.0 * m * n * k / (t.cpuMs * 1e-3) * 1e-9;
  return r;
}

GemmResult cpuSgemm(int size) {
  using Clock = std::chrono::steady_clock;
  std::vector<float> a(size_t(size) * size, 0.5f), b(a.size(), 0.25f), c(a.size());
  double best = 1e30, bestCpu = 1e30;
  for (int r = 0; r < 3; ++r) {
    auto t0 = Clock::now();
    const double cpu0 = processCpuSeconds();
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, size, size, size, 1.0f, a.data(), size, b.data(),
                size, 0.0f, c.data(), size);
    bestCpu = std::min(bestCpu, processCpuSeconds() - cpu0);
    best = std::min(best, std::chrono::duration<double>(Clock::now() - t0).count());
  }
  GemmResult g;
  g.gflops = 2.0 * size * double(size) * size / best * 1e-9;
  g.gflopsPerCpuSecond = 2.0 * size * double(size) * size / bestCpu * 1e-9;
  return g;
}

double cpuSgemmGflops(int size) {
  return cpuSgemm(size).gflops;
}

}  // namespace lfgi::bench
