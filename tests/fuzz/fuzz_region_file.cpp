// libFuzzer target: the region-file reader (core/region_file.h RegionFile::open + readCell of every cell).
// Any input must give cells that pass validate() or an lfgi::Error whose message starts with the source
// name; a crash, a sanitizer report, a leak or any other exception type is a finding.
// The bytes are the whole file, so the head's size and checksum guards, the index's tiling and the
// records' checksums are what gets fuzzed (the checksums keep most mutations out of the field decoder, as
// they keep corruption out of it; the seeded tests in core/region_file_test.cpp reach it with overrides).
// Seeds: tests/fuzz/make_seeds.cpp writes small valid regions.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <span>

#include "core/error.h"
#include "core/region_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static constexpr char kName[] = "fuzz.lfgr";
  try {
    const lfgi::RegionFile f =
        lfgi::RegionFile::open(std::span(reinterpret_cast<const std::byte*>(data), size), kName);
    for (size_t i = 0; i < f.cells().size(); ++i) f.readCell(i).validate(kName);
  } catch (const lfgi::Error& e) {
    if (std::strncmp(e.what(), kName, sizeof(kName) - 1) != 0) {
      std::fprintf(stderr, "error does not name the file: '%s'\n", e.what());
      std::abort();
    }
  }
  return 0;
}
