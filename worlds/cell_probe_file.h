// Reading back cells/cell_X_Z.probes of a world directory (written by worlds::writeCell,
// worlds/world_cells.h: "LFPR", version 1, count, count flag bytes, count x 3 float relocation offsets).
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

#include <glm/glm.hpp>

#include "worlds/synthetic_world.h"

namespace lfgi::worlds {

struct CellProbeFile {
  std::vector<uint8_t> flags;      // ProbeFlag bits per probe of the cell's grid
  std::vector<glm::vec3> offsets;  // relocation per probe
};

// nullopt when the file does not exist. Throws lfgi::Error naming the file when it is truncated, has
// another magic / version, its length disagrees with its count, or an offset is not finite.
std::optional<CellProbeFile> readCellProbes(const std::filesystem::path& worldDir, CellCoord c);

}  // namespace lfgi::worlds
