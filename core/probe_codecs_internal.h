// Shared pieces of the baseline probe codecs (core/probe_codecs.h): the common header and field checks on
// top of core/byte_stream.h. Not a public interface: only the probe_codec*.cpp files include it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/byte_stream.h"
#include "core/probe_field.h"

namespace lfgi::codec_detail {

using lfgi::ByteReader;
using lfgi::ByteWriter;
using lfgi::exposureScale;

// magic[4] | u8 version | u16 resolution | u32 probes  (11 bytes)
struct Header {
  char magic[4];
  uint8_t version = 1;
  int resolution = 0;
  uint32_t probes = 0;
};
void writeHeader(ByteWriter& w, const Header& h);
// Reads and checks the header against the expected magic/version and out's resolution and probe count.
Header readHeader(ByteReader& r, const char magic[4], uint8_t version, const ProbeField& out);

// Throws unless f's resolution, probe count and radiance size agree and every radiance value is finite.
void checkField(const char* codec, const ProbeField& f);
// Sizes out.radiance for out's grid and resolution (zeros) and clears out.irradiance.
void prepareOut(ProbeField& out);

}  // namespace lfgi::codec_detail
