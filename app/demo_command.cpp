// `lfgi demo`: the newest end-to-end path that exists, run on this machine's Vulkan device.
// A sky-like environment (gradient sky, dark ground, a bright sun lobe) is stored in an octahedral
// radiance map; the GPU convolves it to an irradiance map (exact solid angles); the CPU computes the
// same integral and the SH L1/L2 approximations (Ramamoorthi & Hanrahan 2001). Writes EXR + PNG maps,
// a side-by-side picture, a Chrome trace and report.{json,md} with the measured errors and timings.
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>

#include "app/commands.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/image.h"
#include "core/metrics.h"
#include "core/octahedral.h"
#include "core/sh.h"
#include "core/trace.h"
#include "gpu/context.h"
#include "gpu/irradiance_pass.h"

namespace lfgi::app {
namespace {

// Radiance of the demo environment in direction d (+Y up), linear RGB. Smooth sky + a sun lobe that
// L2 cannot represent: the SH error in the report is the real cost of a 9-coefficient fallback.
glm::vec3 demoSky(glm::vec3 d) {
  const glm::vec3 sunDir = glm::normalize(glm::vec3(0.4f, 0.6f, 0.3f));
  float up = std::max(d.y, 0.0f);
  glm::vec3 zenith(0.25f, 0.45f, 0.95f), horizon(0.9f, 0.85f, 0.8f), ground(0.12f, 0.1f, 0.08f);
  glm::vec3 sky = d.y >= 0.0f ? glm::mix(horizon, zenith, std::sqrt(up)) : ground;
  float sun = 60.0f * std::exp(80.0f * (glm::dot(d, sunDir) - 1.0f));
  return sky + glm::vec3(1.0f, 0.92f, 0.8f) * sun;
}

Image mapImage(const std::vector<glm::vec3>& texels, int n) {
  Image img(n, n, {"R", "G", "B"});
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) img.at(i, j, c) = texels[size_t(j) * size_t(n) + size_t(i)][c];
  return img;
}

// Nearest-neighbour upscale of an n x n map into a size x size panel at (x0, 0) of `dst`, times `scale`.
void blitPanel(Image& dst, const std::vector<glm::vec3>& texels, int n, int x0, int size, float scale) {
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      const glm::vec3& v = texels[size_t(y * n / size) * size_t(n) + size_t(x * n / size)];
      for (int c = 0; c < 3; ++c) dst.at(x0 + x, y, c) = v[c] * scale;
    }
}

}  // namespace

int runDemo(const DemoOptions& opt) {
  const std::filesystem::path out = opt.outDir;
  const int n = opt.resolution;
  const int m = std::max(4, n / 2);
  TraceWriter trace;
  trace.setThreadName("main");
  nlohmann::ordered_json report;

  std::unique_ptr<gpu::Context> ctx;
  {
    TraceScope s(&trace, "create Vulkan context");
    ctx = gpu::createContext();
  }
  spdlog::info("device: {} ({})", ctx->info.name, ctx->info.type);

  std::vector<glm::vec3> radiance(size_t(n) * size_t(n));
  {
    TraceScope s(&trace, "evaluate environment");
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) radiance[size_t(j) * size_t(n) + size_t(i)] = demoSky(octTexelDirection(i, j, n));
  }

  double gpuMs = 0.0;
  std::vector<glm::vec3> irrGpu;
  {
    TraceScope s(&trace, "GPU irradiance convolution (incl. upload, readback)");
    gpu::IrradianceConvolution pass(*ctx);
    irrGpu = pass.run(radiance, n, m, 1, &gpuMs);
  }
  double now = trace.nowUs();
  trace.complete("GPU irradiance pass (device timestamps)", "gpu", now - gpuMs * 1e3, gpuMs * 1e3);

  std::vector<glm::vec3> irrCpu(size_t(m) * size_t(m)), irrL1(irrCpu.size()), irrL2(irrCpu.size());
  std::span<const float> rgb(&radiance[0].x, radiance.size() * 3);
  {
    TraceScope s(&trace, "CPU brute-force irradiance + SH");
    std::vector<double> omega = octTexelSolidAngles(n);
    ShL1 l1 = shProject<4>(rgb, n, omega);
    ShL2 l2 = shProject<9>(rgb, n, omega);
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) {
        glm::vec3 normal = octTexelDirection(i, j, m);
        size_t k = size_t(j) * size_t(m) + size_t(i);
        irrCpu[k] = bruteForceIrradiance(rgb, n, normal, omega);
        irrL1[k] = shIrradiance(l1, normal);
        irrL2[k] = shIrradiance(l2, normal);
      }
  }
  auto flat = [](const std::vector<glm::vec3>& v) { return std::span<const float>(&v[0].x, v.size() * 3); };
  const double gpuVsCpu = relativeRms(flat(irrGpu), flat(irrCpu));
  const double l1Err = relativeRms(flat(irrL1), flat(irrCpu));
  const double l2Err = relativeRms(flat(irrL2), flat(irrCpu));

  {
    TraceScope s(&trace, "write images");
    writeExr(out / "radiance.exr", mapImage(radiance, n));
    writeExr(out / "irradiance_gpu.exr", mapImage(irrGpu, m));
    writeExr(out / "irradiance_sh_l2.exr", mapImage(irrL2, m));
    // Side by side: radiance | irradiance (GPU, exact) | SH L2 irradiance | |L2 - exact| / exact x 10.
    const int size = 256, gap = 8;
    Image panel(4 * size + 3 * gap, size, {"R", "G", "B"});
    double meanIrr = 0.0;
    for (const glm::vec3& v : irrCpu) meanIrr += (v.r + v.g + v.b) / 3.0;
    meanIrr /= double(irrCpu.size());
    const float scale = float(0.35 / meanIrr);
    blitPanel(panel, radiance, n, 0, size, scale * std::numbers::pi_v<float>);
    blitPanel(panel, irrGpu, m, size + gap, size, scale);
    blitPanel(panel, irrL2, m, 2 * (size + gap), size, scale);
    std::vector<glm::vec3> relErr(irrCpu.size());
    for (size_t k = 0; k < relErr.size(); ++k)
      relErr[k] = glm::vec3(10.0f * glm::length(irrL2[k] - irrCpu[k]) / glm::length(irrCpu[k]));
    blitPanel(panel, relErr, m, 3 * (size + gap), size, 1.0f);
    writePng(out / "demo.png", panel, 0.0f, ToneMap::kReinhard);
    writePng(out / "radiance.png", mapImage(radiance, n), std::log2(scale * std::numbers::pi_v<float>));
  }

  report["device"] = ctx->info.name;
  report["device_type"] = ctx->info.type;
  report["radiance_resolution"] = n;
  report["irradiance_resolution"] = m;
  report["gpu_irradiance_ms"] = gpuMs;
  report["gpu_vs_cpu_irr_rel_rms"] = gpuVsCpu;
  report["sh_l1_irr_rel_rms"] = l1Err;
  report["sh_l2_irr_rel_rms"] = l2Err;
  report["validation_errors"] = ctx->validationErrors.load();
  writeFileAtomic(out / "report.json", report.dump(2) + "\n");
  trace.save(out / "trace.json");

  std::string md = fmt::format(
      "# lfgi demo\n\n"
      "Device: **{}** ({}). Octahedral radiance map {}x{}, irradiance map {}x{}.\n\n"
      "![radiance | exact irradiance (GPU) | SH L2 irradiance | L2 relative error x10](demo.png)\n\n"
      "Panels: radiance | exact irradiance (GPU) | SH L2 irradiance | L2 relative error (brighter = larger; x10, tone-mapped).\n\n"
      "| measure | value |\n|---|---|\n"
      "| GPU irradiance pass (device time) | {:.3f} ms |\n"
      "| GPU vs CPU exact irradiance, relative RMS | {:.2e} |\n"
      "| SH L1 irradiance vs exact, relative RMS | {:.2f} % |\n"
      "| SH L2 irradiance vs exact, relative RMS | {:.2f} % |\n\n"
      "Files: radiance.exr, irradiance_gpu.exr, irradiance_sh_l2.exr (linear float), report.json, "
      "trace.json (open in https://ui.perfetto.dev).\n",
      ctx->info.name, ctx->info.type, n, n, m, m, gpuMs, gpuVsCpu, 100.0 * l1Err, 100.0 * l2Err);
  writeFileAtomic(out / "report.md", md);

  spdlog::info("GPU irradiance {:.3f} ms; GPU vs CPU rel RMS {:.2e}; SH L1 {:.2f} %, L2 {:.2f} % rel RMS", gpuMs,
               gpuVsCpu, 100.0 * l1Err, 100.0 * l2Err);
  spdlog::info("wrote {}", (out / "report.md").string());
  if (gpuVsCpu > 1e-4) fail("GPU and CPU irradiance disagree (relative RMS {:.2e} > 1e-4) on '{}'", gpuVsCpu, ctx->info.name);
  return 0;
}

}  // namespace lfgi::app
