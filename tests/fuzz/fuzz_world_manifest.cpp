// libFuzzer target: the world manifest parser (worlds/world_cells.h parseWorldManifest, the body of
// readWorldManifest). Any text must give valid WorldParams or an lfgi::Error naming the file; a JSON
// library exception escaping, a crash or a sanitizer report is a finding. Seeds: make_seeds.cpp.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string_view>

#include "core/error.h"
#include "worlds/world_cells.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  constexpr char kName[] = "fuzz/world.json";
  try {
    const lfgi::worlds::WorldParams p =
        lfgi::worlds::parseWorldManifest(std::string_view(reinterpret_cast<const char*>(data), size), kName);
    p.validate();  // accepted means valid
  } catch (const lfgi::Error& e) {
    if (std::strncmp(e.what(), kName, sizeof(kName) - 1) != 0) {
      std::fprintf(stderr, "error does not name the file: '%s'\n", e.what());
      std::abort();
    }
  }
  return 0;
}
