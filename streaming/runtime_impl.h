// What lfgi::Runtime holds (include/lfgi/runtime.h), shared by runtime.cpp and runtime_vulkan.cpp; internal.
#pragma once

#include <glm/glm.hpp>

#include <exception>
#include <memory>

#include "lfgi/runtime.h"
#include "streaming/cell_file_source.h"
#include "streaming/streaming_manager.h"
#include "streaming/vir_relight_source.h"

namespace lfgi {

struct Runtime::Impl {
  RuntimeConfig config;
  std::unique_ptr<gpu::Context> virContext;  // VIR visibility: lfgi's own device, or the host's adopted
  std::unique_ptr<streaming::CellFileSource> source;
  std::unique_ptr<streaming::VirRelightSource> vir;  // over source when config.virVisibility
  std::unique_ptr<streaming::StreamingManager> manager;
  glm::vec3 camera{0.0f};        // the last update()'s camera
  float timeOfDayHours = 12.0f;  // and its time of day

  // Opens the runtime over virContext (null: no VIR visibility; config.virVisibility must then be false).
  static std::unique_ptr<Impl> open(const RuntimeConfig& config, std::unique_ptr<gpu::Context> virContext);
};

// The public API's float[3] as a vector.
inline glm::vec3 vec3Of(const float* v) {
  return {v[0], v[1], v[2]};
}

// RuntimeError naming the first bad RuntimeConfig field or a world directory without world.json.
void checkRuntimeConfig(const RuntimeConfig& config);

// Runs f; every internal error (lfgi::Error and the standard exceptions) leaves as RuntimeError.
template <typename F>
auto asRuntimeError(F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const RuntimeError&) {
    throw;
  } catch (const std::exception& e) {
    throw RuntimeError(e.what());
  }
}

}  // namespace lfgi
