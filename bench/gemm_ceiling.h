// GEMM ceilings shared by the benchmarks that report "fraction of the device's GEMM ceiling" (ceilings,
// codec_decode): the project's barrier-free GEMM kernel on the Vulkan device (shaders/gemm_rowstrip.comp,
// checked against OpenBLAS) and OpenBLAS sgemm on all CPU threads. Best of several repetitions.
#pragma once

#include <vulkan/vulkan.h>

#include <functional>

#include "gpu/context.h"
#include "gpu/program.h"

namespace lfgi::bench {

// Best device time (ms, GPU timestamps) of `reps` submissions of what `record` records.
double bestGpuMs(gpu::Context& ctx, int reps, const std::function<void(VkCommandBuffer)>& record);

// Device time and the process CPU time spent over the submission (best of `reps` each). On a CPU device
// (lavapipe) the CPU time is the work itself, so its rate does not drop when other processes share the cores,
// unlike the wall-clock device time; on a real GPU it is only the host's submission cost.
struct GpuTime {
  double ms = 0.0, cpuMs = 0.0;
};
GpuTime bestGpuTime(gpu::Context& ctx, int reps, const std::function<void(VkCommandBuffer)>& record);

// Process CPU time (all threads) in seconds, CLOCK_PROCESS_CPUTIME_ID.
double processCpuSeconds();

struct GemmResult {
  double gflops = 0.0, maxRelError = 0.0;  // error: max |C - C(OpenBLAS)| / max |C(OpenBLAS)|
  double gflopsPerCpuSecond = 0.0;         // GFLOP per second of process CPU time (see GpuTime)
};

// size^3 GEMM with `program` = gemm_rowstrip (shared/ceilings.h GemmParams; size a multiple of 4).
GemmResult gpuGemm(gpu::Context& ctx, gpu::Program& program, int size);

// OpenBLAS sgemm size^3 on all threads, GFLOP/s.
double cpuSgemmGflops(int size);
// The same, also per second of process CPU time.
GemmResult cpuSgemm(int size);

}  // namespace lfgi::bench
