// lfgi::Runtime (include/lfgi/runtime.h): the public facade over CellFileSource + StreamingManager. Every
// internal error (lfgi::Error and the standard exceptions) leaves as lfgi::RuntimeError with its message.
#include "lfgi/runtime.h"

#include <spdlog/spdlog.h>

#include <cmath>
#include <system_error>

#include "core/error.h"
#include "streaming/http_region_source.h"
#include "streaming/runtime_impl.h"

#ifndef LFGI_VERSION_STRING
#error "LFGI_VERSION_STRING must be defined by the build"
#endif

namespace lfgi {

namespace {}  // namespace

void checkRuntimeConfig(const RuntimeConfig& c) {
  if (c.world.empty())
    throw RuntimeError("lfgi runtime: RuntimeConfig::world is empty (a baked world directory)");
  if (c.memoryBudgetBytes == 0)
    throw RuntimeError(
        "lfgi runtime: RuntimeConfig::memoryBudgetBytes is 0 (the decoded light field needs a budget)");
  if (!(std::isfinite(c.decodeRadius) && c.decodeRadius > 0.0f))
    throw RuntimeError(
        fmt::format("lfgi runtime: RuntimeConfig::decodeRadius = {} (must be finite, > 0)", c.decodeRadius));
  if (!(std::isfinite(c.keepRadius) && c.keepRadius > c.decodeRadius))
    throw RuntimeError(
        fmt::format("lfgi runtime: RuntimeConfig::keepRadius = {} (must be finite, > decodeRadius {})",
                    c.keepRadius, c.decodeRadius));
  if (c.ioThreads < 0 || c.ioThreads > 64)
    throw RuntimeError(fmt::format("lfgi runtime: RuntimeConfig::ioThreads = {} (0 to 64)", c.ioThreads));
  if (!(std::isfinite(c.activateBudgetMs) && c.activateBudgetMs > 0.0))
    throw RuntimeError(fmt::format("lfgi runtime: RuntimeConfig::activateBudgetMs = {} (must be finite, > 0)",
                                   c.activateBudgetMs));
  std::error_code ec;
  if (!streaming::isHttpUrl(c.world.string()) &&
      !std::filesystem::is_regular_file(c.world / "world.json", ec))
    throw RuntimeError(fmt::format(
        "{}: no world.json (not a world directory; `lfgi world generate` makes one)", c.world.string()));
}

namespace {

void checkFrame(const Frame& f) {
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(f.position[i]) || !std::isfinite(f.direction[i]) || !std::isfinite(f.velocity[i]))
      throw RuntimeError("lfgi runtime: update(): Frame position, direction and velocity must be finite");
  if (!(f.timeOfDayHours >= 0.0f && f.timeOfDayHours <= 24.0f))
    throw RuntimeError(
        fmt::format("lfgi runtime: update(): Frame::timeOfDayHours = {} (0 to 24)", f.timeOfDayHours));
  if (!(std::isfinite(f.dtSeconds) && f.dtSeconds > 0.0f))
    throw RuntimeError(
        fmt::format("lfgi runtime: update(): Frame::dtSeconds = {} (must be finite, > 0)", f.dtSeconds));
}

}  // namespace

std::unique_ptr<Runtime::Impl> Runtime::Impl::open(const RuntimeConfig& config,
                                                   std::unique_ptr<gpu::Context> virContext) {
  auto impl = std::make_unique<Impl>();
  impl->config = config;
  impl->virContext = std::move(virContext);
  streaming::CellFileSourceOptions so;
  const bool url = streaming::isHttpUrl(config.world.string());
  if (url)
    so.worldUrl = config.world.string();
  else
    so.worldDir = config.world;
  so.decoder = streaming::DecoderChoice::Cpu;
  impl->source = std::make_unique<streaming::CellFileSource>(so);
  streaming::CellSource* source = impl->source.get();
  if (config.virVisibility) {
    if (!impl->virContext) fail("lfgi runtime: virVisibility needs a Vulkan device");
    streaming::VirRelightOptions vo;
    vo.relightByVir = false;  // time of day from the baked keys; visibility from the geometry
    vo.maxRange = impl->source->layout().cellSize;  // as `lfgi render --probes codec`
    impl->vir = std::make_unique<streaming::VirRelightSource>(
        *impl->source, *impl->virContext, vo,
        streaming::neighbourhoodSurfelProvider(url ? streaming::worldSurfelProvider(impl->source->world())
                                                   : streaming::worldSurfelProvider(config.world),
                                               impl->source->layout()));
    source = impl->vir.get();
  }
  streaming::StreamingConfig sc;
  sc.memoryBudgetBytes = config.memoryBudgetBytes;
  sc.decodeRadius = config.decodeRadius;
  sc.keepRadius = config.keepRadius;
  sc.ioThreads = config.ioThreads;
  sc.activateBudgetMs = config.activateBudgetMs;
  sc.validate();
  impl->manager = std::make_unique<streaming::StreamingManager>(*source, sc);
  return impl;
}

std::unique_ptr<Runtime> Runtime::open(const RuntimeConfig& config) {
  checkRuntimeConfig(config);
  return asRuntimeError([&] {
    std::unique_ptr<gpu::Context> ctx;
    if (config.virVisibility) {
      try {
        ctx = gpu::createContext();
      } catch (const Error& e) {
        throw RuntimeError(fmt::format(
            "lfgi runtime: VIR visibility (RuntimeConfig::virVisibility) needs a Vulkan device: {}",
            e.what()));
      }
    }
    return std::unique_ptr<Runtime>(new Runtime(Impl::open(config, std::move(ctx))));
  });
}

Runtime::Runtime(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Runtime::~Runtime() = default;

FrameReport Runtime::update(const Frame& frame) {
  checkFrame(frame);
  return asRuntimeError([&] {
    streaming::FrameInput in;
    in.position = vec3Of(frame.position);
    in.direction = vec3Of(frame.direction);
    in.velocity = vec3Of(frame.velocity);
    in.timeOfDayHours = frame.timeOfDayHours;
    in.dtSeconds = frame.dtSeconds;
    const streaming::FrameStats s = impl_->manager->update(in);
    impl_->camera = in.position;
    impl_->timeOfDayHours = in.timeOfDayHours;
    FrameReport r;
    r.frame = s.frame;
    r.residentCells = s.resident;
    r.loadingCells = s.loading;
    r.failedCells = s.failed;
    r.bytesResident = s.bytesResident;
    r.updateMs = s.updateMs;
    return r;
  });
}

void Runtime::sample(std::span<const float> positions, std::span<const float> normals,
                     std::span<GiSample> out) const {
  if (positions.size() != out.size() * 3 || normals.size() != out.size() * 3)
    throw RuntimeError(fmt::format(
        "lfgi runtime: sample(): {} position and {} normal floats for {} samples (3 floats per point each)",
        positions.size(), normals.size(), out.size()));
  for (size_t i = 0; i < out.size(); ++i) {
    const streaming::IrradianceSample s =
        impl_->manager->sample(vec3Of(positions.data() + 3 * i), vec3Of(normals.data() + 3 * i));
    out[i] = GiSample{{s.irradiance.x, s.irradiance.y, s.irradiance.z}, s.fallbackWeight, s.missing};
  }
}

float Runtime::worldSizeX() const {
  const streaming::WorldLayout l = impl_->source->layout();
  return float(l.cells.x) * l.cellSize;
}
float Runtime::worldSizeZ() const {
  const streaming::WorldLayout l = impl_->source->layout();
  return float(l.cells.y) * l.cellSize;
}
float Runtime::cellSize() const {
  return impl_->source->layout().cellSize;
}

const char* runtimeVersion() {
  return LFGI_VERSION_STRING;
}

}  // namespace lfgi
