// lfgi runtime: the light field of a baked world streamed around a camera, for a host engine's frame loop
// (docs/embedding.md). The one public header of the installed package (`find_package(lfgi CONFIG)`,
// target lfgi::runtime); everything else in the source tree is internal.
//
// Contract
//   - Runtime::open reads a world baked by `lfgi bake` (WORLD/world.json + WORLD/baked/regions/, the cells
//     packed into region files, or WORLD/baked/cells/*.vdb; a local directory or an http(s):// URL) and
//     keeps every cell's coarse fallback (SH L1) resident from then on, so a point inside the world is
//     never without light, whatever the streaming does.
//   - update() once per frame on the game thread: cells near the camera (and its predicted position) are
//     read, checked and decoded on lfgi's own IO threads (RuntimeConfig::ioThreads) into a slot pool
//     allocated up front from memoryBudgetBytes (resident bytes never exceed it; no frame allocates), then
//     made visible within activateBudgetMs of game-thread time and cross-faded in; far cells are dropped.
//   - sample() on the game thread: irradiance at world points from the resident cells, blended with the
//     fallbacks while cells fade in. It reads only what update() left; it never blocks on IO.
//   - Threading: open, update, sample, report and the destructor on one thread (the game thread). No call
//     is reentrant; none may run concurrently with another on the same Runtime. Distinct Runtimes are
//     independent. The destructor joins lfgi's IO threads.
//   - Errors are lfgi::RuntimeError (a std::runtime_error) whose message names the file or the setting and
//     the problem: a missing world, an unreadable cell directory, a bad setting (budget 0, radius <= 0),
//     a budget smaller than one cell. A cell file that fails at load later is not an error: it is logged,
//     counted (FrameReport::failedCells) and keeps its fallback.
//   - No Embree, libtorch or OpenVDB header reaches the host; the library links no Embree or libtorch.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>

#if defined(__GNUC__)
#define LFGI_API __attribute__((visibility("default")))
#else
#define LFGI_API
#endif

namespace lfgi {

class LFGI_API RuntimeError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct RuntimeConfig {
  // The world directory (world.json + baked/regions/ or baked/cells/), or an http(s):// URL of one on a
  // static server (regions read by range requests; docs/embedding.md "Serving worlds"; with virVisibility
  // the cells' geometry is generated from the served world.json, as the bake did).
  std::filesystem::path world;
  std::size_t memoryBudgetBytes = std::size_t(256) << 20;  // decoded light field, > 0
  float decodeRadius = 160.0f;                             // m: cells nearer than this are loaded (> 0)
  float keepRadius = 224.0f;      // m: resident cells farther than this are dropped (> decodeRadius)
  int ioThreads = 2;              // lfgi's IO threads, 0..64 (0: loads inline in update())
  double activateBudgetMs = 2.0;  // game-thread time per frame for making cells visible
  // Visibility (the probes' distance moments, so light does not cross walls) regenerated from each cell's
  // geometry by VIR when it loads (docs/ARCHITECTURE.md, "Where visibility comes from"), on lfgi's IO
  // threads on a Vulkan device: lfgi's own compute device with open(config), the host's with
  // open(config, device) (lfgi/runtime_vulkan.h). false: the codec's decoded visibility, which for the
  // shipped SH codec is none (light leaks through walls); no Vulkan device is then needed for open(config).
  bool virVisibility = true;
};

struct Frame {
  float position[3] = {0.0f, 0.0f, 0.0f};    // camera, world metres (y up)
  float direction[3] = {0.0f, 0.0f, -1.0f};  // view direction (cells ahead load first)
  float velocity[3] = {0.0f, 0.0f, 0.0f};    // m/s: loads follow the predicted position (0 on a teleport)
  float timeOfDayHours = 12.0f;              // [0, 24]: the fallback and SH cells follow it between keys
  float dtSeconds = 1.0f / 60.0f;            // > 0: drives the cross-fades
};

struct FrameReport {
  std::uint64_t frame = 0;
  int residentCells = 0;          // visible (maybe still fading in)
  int loadingCells = 0;           // queued, loading, or loaded and not yet visible
  int failedCells = 0;            // cells whose load failed this frame (they keep their fallback)
  std::size_t bytesResident = 0;  // <= RuntimeConfig::memoryBudgetBytes
  double updateMs = 0.0;          // game-thread time of this update()
};

struct GiSample {
  float irradiance[3] = {0.0f, 0.0f, 0.0f};  // linear RGB irradiance at the point for its normal
  float fallbackWeight = 1.0f;               // 0: all from decoded cells .. 1: all from fallbacks
  bool missing = false;                      // outside the world: no light at all
};

class VulkanShading;
struct VulkanDevice;  // lfgi/runtime_vulkan.h

class LFGI_API Runtime {
 public:
  // Throws RuntimeError (see the contract above; with virVisibility, also when no Vulkan device exists).
  static std::unique_ptr<Runtime> open(const RuntimeConfig& config);
  // The same on the host's device (lfgi/runtime_vulkan.h): lfgi creates no device; VIR visibility runs on
  // device.queue from lfgi's IO threads under device.queueMutex.
  static std::unique_ptr<Runtime> open(const RuntimeConfig& config, const VulkanDevice& device);
  ~Runtime();
  Runtime(const Runtime&) = delete;
  Runtime& operator=(const Runtime&) = delete;

  // Once per frame. Throws RuntimeError for a non-finite or out-of-range Frame field.
  FrameReport update(const Frame& frame);
  // GI at positions[i] (xyz) for unit normals[i] (xyz) into out[i]; positions and normals hold 3 floats
  // per point, out one GiSample per point (sizes checked: RuntimeError).
  void sample(std::span<const float> positions, std::span<const float> normals,
              std::span<GiSample> out) const;

  // The world's extent in metres (x and z from the origin) and its cell size.
  float worldSizeX() const;
  float worldSizeZ() const;
  float cellSize() const;

 private:
  friend class VulkanShading;  // lfgi/runtime_vulkan.h
  struct Impl;
  explicit Runtime(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// "MAJOR.MINOR.PATCH" of the library the host runs against.
LFGI_API const char* runtimeVersion();

}  // namespace lfgi
