// libFuzzer target: the Draco surfel decoder (worlds/surfels.h decodeSurfels). Any input must give
// finite surfels or an lfgi::Error naming the source; a crash, sanitizer report, leak or other exception
// type is a finding. Seeds: tests/fuzz/make_seeds.cpp (small encoded clouds).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "core/error.h"
#include "worlds/surfels.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  constexpr char kName[] = "fuzz.surfels";
  try {
    const auto surfels = lfgi::worlds::decodeSurfels({reinterpret_cast<const std::byte*>(data), size}, kName);
    for (const lfgi::worlds::Surfel& s : surfels)
      for (int c = 0; c < 4; ++c)
        if (!std::isfinite(s.positionRadius[c]) || !std::isfinite(s.normal[c]) ||
            !std::isfinite(s.emission[c]))
          std::abort();
  } catch (const lfgi::Error& e) {
    if (std::strncmp(e.what(), kName, sizeof(kName) - 1) != 0) {
      std::fprintf(stderr, "error does not name the source: '%s'\n", e.what());
      std::abort();
    }
  }
  return 0;
}
