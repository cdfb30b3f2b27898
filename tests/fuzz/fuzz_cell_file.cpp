// libFuzzer target: the cell-file reader (core/cell_file.h decodeCellFile). Any input must give either a
// CellFile that passes validate() or an lfgi::Error whose message starts with the source name; a crash, a
// sanitizer report, a leak or any other exception type is a finding (libFuzzer stops and saves the input).
//
// The first byte picks how the rest is used:
//   even: the bytes are the whole file, so the size, trailer and checksum guards are what gets fuzzed;
//   odd:  with LFGI_FUZZ_RESEAL=1 in the environment, the bytes are the OpenVDB stream and the harness
//         appends a valid trailer (length + XXH3-64), so mutations get past the checksum into OpenVDB's
//         parser and the field cross-checks, as a file from a buggy writer (or a forger who recomputes the
//         checksum) would; otherwise odd is treated like even.
// The resealed mode is outside the reader's contract (cell_file.h: the checksum guards against
// corruption, not forgery) and finds undefined behaviour inside OpenVDB 10 itself within seconds
// (InternalNode::readTopology loads a flipped byte as a bool, NodeUnion.h:74), so the bounded CI run
// (scripts/fuzz.sh) leaves it off.
// Seeds: tests/fuzz/make_seeds.cpp writes both forms of a few small valid cells.
#include <xxhash.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "core/cell_file.h"
#include "core/error.h"

namespace {

constexpr char kName[] = "fuzz.vdb";

void check(std::span<const std::byte> bytes) {
  try {
    const lfgi::CellFile c = lfgi::decodeCellFile(bytes, kName);
    c.validate(kName);  // what the reader accepted is a valid cell
  } catch (const lfgi::Error& e) {
    if (std::strncmp(e.what(), kName, sizeof(kName) - 1) != 0) {
      std::fprintf(stderr, "error does not name the file: '%s'\n", e.what());
      std::abort();
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const auto* body = reinterpret_cast<const std::byte*>(data + 1);
  const size_t n = size - 1;
  static const bool reseal = [] {
    const char* v = std::getenv("LFGI_FUZZ_RESEAL");
    return v && std::string(v) == "1";
  }();
  if ((data[0] & 1) == 0 || !reseal) {
    check({body, n});
    return 0;
  }
  std::vector<std::byte> sealed(body, body + n);
  const uint64_t length = n, sum = XXH3_64bits(body, n);
  const std::byte* magic = reinterpret_cast<const std::byte*>("LFGICELL");
  sealed.insert(sealed.end(), magic, magic + 8);
  sealed.insert(sealed.end(), reinterpret_cast<const std::byte*>(&length),
                reinterpret_cast<const std::byte*>(&length) + 8);
  sealed.insert(sealed.end(), reinterpret_cast<const std::byte*>(&sum),
                reinterpret_cast<const std::byte*>(&sum) + 8);
  check(sealed);
  return 0;
}
