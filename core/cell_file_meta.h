// A cell's fields as an OpenVDB metadata map, apart from the container that carries them: the cell file
// (core/cell_file.h: an OpenVDB stream with a MaskGrid topology) and the region file (core/region_file.h:
// many cells' fields in a compact binary form with a probe mask) write the same map and read it through
// the same checks. Private to core, like core/vdb_container.h (OpenVDB's headers).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>

#include <openvdb/openvdb.h>

#include "core/cell_file.h"

namespace lfgi::cellmeta {

// Every field of the cell, blobs included (encodeCellFile's metadata; validates the cell first, errors
// start with "encodeCellFile"), with the test seam's overrides applied.
openvdb::MetaMap fields(const CellFile& cell, std::span<const detail::CellFileOverride> overrides = {});

// Fills c.active (or leaves it empty when every probe of the grid is active) from the container's
// topology, checking that it holds exactly probeCount active probes inside c.grid; throws lfgi::Error
// starting with the reader's name.
using TopologyReader = std::function<void(int64_t probeCount, CellFile& c)>;

// The cell back from its fields, with every check of core/cell_file.h's reader contract in its order;
// parts gets the bytes by part except total (the container knows it). Errors start with `name`.
CellFile decode(const openvdb::MetaMap& meta, const std::string& name, const TopologyReader& topology,
                CellFileBytes& parts);

}  // namespace lfgi::cellmeta
