// Shared by `lfgi bake` and `lfgi bake-status`: the selected cells.
#pragma once

#include <vector>

#include "app/commands.h"
#include "bake/world_bake.h"

namespace lfgi::app {

// --cells (X,Z or index ranges; all when empty), then --array-index/--array-size's share.
std::vector<worlds::CellCoord> selectBakeCells(const worlds::SyntheticWorld& world,
                                               const WorldBakeOptions& options);

}  // namespace lfgi::app
