// Internal to bake/: the tiled, interruptible driver both path-traced references share (renderReference in
// reference_render.cpp, renderShadingReference in shading_inputs.cpp). It validates the options and the
// camera, allocates the image with the given layers, derives the path options, the active discs and the
// per-render random key (the same key for both renderers, so their totals agree sample for sample), runs
// `tile` over every tile on the TBB pool with progress and Ctrl-C, and fills the result's counters.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "bake/path_trace.h"
#include "bake/reference_render.h"

namespace lfgi::bake::detail {

struct TileJob {
  const PathOptions& path;
  const Discs& discs;
  uint64_t key;        // PathRng key of this render
  int x0, y0, x1, y1;  // pixel range [x0, x1) x [y0, y1)
};

RenderResult renderTiled(const worlds::SkyModel& sky, const PinholeCamera& camera, const RenderOptions& o,
                         std::vector<std::string> layers, bool showProgress,
                         const std::function<void(const TileJob& job, Image& image, uint64_t& rays)>& tile);

}  // namespace lfgi::bake::detail
