// `lfgi fly / profile --render WxH [--every N]` (docs/ARCHITECTURE.md "Rendered fly-through"): frames of the
// flight drawn on the Vulkan device from the streaming manager's state in that frame. Each rendered frame is
// a G-buffer of the world's own geometry around the camera (ray cast on the device; the cells within the
// shading distance) shaded by the probe shading pass (gpu/probe_shading_pass.h) from the device copy of the
// resident cells (streaming/device_shading.h): full cells, cells fading in, relit cells, and the SH L1
// fallback where nothing is resident; sun and moon light with shadow rays, indirect from the probes.
//
// Output under OUT: frames/frame_NNNNN.png (rendered frames numbered from 0, one exposure for the whole
// flight: the first frame's), strip.png (up to 8 frames spread over the flight in one row, for the report),
// flight.mp4 (ffmpeg, when installed) and render_frames.csv (per rendered frame: device ms of the G-buffer
// and the shading from GPU timestamps, upload, pixels missing GI, the fallback's share, an image hash).
// summary() is the summary.json block "render".
//
// Reference frames: frames/frame_NNNNN_reference.png (same exposure) and _error.png (indirect heat map,
// bake/shading_view.h errorHeatMap), and the relative RMS of the total and of the indirect light over the
// pixels shaded from probes or fallbacks (the "reference" list of the block).
//
// A pixel is missing GI when it shows a surface (not sky, not a back face inside solid) and gets light
// from no probe and no fallback (ShadeOutput: diffuse.w = 0 and direct.w = 0).
#pragma once

#include <nlohmann/json.hpp>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "core/trace.h"
#include "streaming/cell_file_source.h"
#include "streaming/flythrough.h"

namespace lfgi::app {

struct FlyRenderOptions {
  int width = 0, height = 0;  // 0: no rendering
  int every = 1;              // render every N-th flight frame (frame 0 first)
  float verticalFovDeg = 60.0f;
  float shadeDistance = 120.0f;  // m: the G-buffer holds the cells within this of the camera
  float fps = 60.0f;             // flight frames per second (the video's rate is fps / every)
  int plannedFrames = 0;         // flight frames planned (spaces the strip's frames over the flight)
  // Rendered frames also path-traced (bake/shading_inputs.h renderShadingReference, Embree, the same view and
  // geometry) and compared, spread over the flight (first, last, between); 0: none.
  int referenceFrames = 0;
  int referenceSpp = 16;
  int referenceBounces = 4;
  std::filesystem::path outDir;
};

// "320x180" -> width, height; throws lfgi::Error naming the text for anything else (each 16 to 4096).
void parseRenderSize(const std::string& text, int& width, int& height);

class FlyRenderer {
 public:
  // source and trace (may be null) outlive the renderer; keepRadius: the manager's.
  FlyRenderer(FlyRenderOptions options, const streaming::CellFileSource& source, float keepRadius,
              TraceWriter* trace);
  ~FlyRenderer();
  FlyRenderer(const FlyRenderer&) = delete;
  FlyRenderer& operator=(const FlyRenderer&) = delete;

  // FlythroughOptions::onFrame: renders the frame when its index is a multiple of `every`.
  void frame(const streaming::FlythroughFrame& f, const streaming::StreamingManager& manager);
  // After the flight: writes strip.png, render_frames.csv and the video; returns the "render" block.
  nlohmann::ordered_json finish();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lfgi::app
