// Baseline probe codecs (docs/docs/DESIGN.md §4): what the generative codec must beat, behind one
// small interface so bench/codec measures every method with the same probes and the same metrics.
//
// What a codec stores: the radiance maps of every probe of a ProbeField (active or not; n x n x 3, the
// core/octahedral.h interior layout). Distance, normal and albedo maps are not part of the baselines'
// payload. Irradiance is what shading reads: SH codecs evaluate it directly from their coefficients (the
// cosine convolution, a runtime would do the same); every other codec's decoded radiance goes through
// deriveIrradiance, which is the capture's own texel-sum (bruteForceIrradiance).
//
// Byte strings are self-describing and all-in: a header (magic, version, probe count, resolution, the
// per-cell exposure scale, model size) plus the payload, so bytes.size() / probeCount is the all-in cost
// per probe. Only the probe layout (grid, positions) is cell metadata outside the codec; decode checks
// the header against it.
//
// FP16 everywhere follows core/half.h (never Inf or NaN). Values are pre-scaled by a per-cell power of
// two so that the largest magnitude is at most 2^14 (docs/DESIGN.md §2: store exposure per cell, never
// overflow); the scale is exact, so a field that fits FP16 round-trips exactly as it would unscaled.
//
// Contracts: encode throws lfgi::Error (naming the codec) for a field whose radiance does not match its
// grid and resolution or holds non-finite values. decode throws lfgi::Error naming the codec for bytes
// that are truncated, carry another codec's magic or a bad version, or disagree with out's layout; it
// never reads outside `bytes`. encode and decode are const and single-threaded (PCA's LAPACK/BLAS calls
// use OpenBLAS's own threads), safe to call from several threads on one codec object.
//
// Adding a codec (e.g. the generative one, from bake/): implement ProbeCodec and add it to the list in
// bench/codec.cpp (see makeBenchCodecs there); nothing else changes.
#pragma once

#include <cstddef>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "core/probe_field.h"

namespace lfgi {

class ProbeCodec {
 public:
  virtual ~ProbeCodec() = default;
  // Stable identifier: the benchmark's "codec" column ("raw_fp16", "sh_l2", "pca", ...).
  virtual std::string name() const = 0;
  // What distinguishes rows of one codec ("level 19", "block 6x6", "target 0.05"); "" if nothing.
  virtual std::string setting() const = 0;
  // Field radiance -> self-describing bytes (see above).
  virtual std::vector<std::byte> encode(const ProbeField& field) const = 0;
  // Bytes -> out.radiance (probeCount * n * n * 3) and, for codecs with a direct route, out.irradiance
  // (probeCount * m * m * 3, m = out.irradianceResolution; other codecs clear it). out.grid and
  // out.resolution must describe the encoded field.
  virtual void decode(std::span<const std::byte> bytes, ProbeField& out) const = 0;
  // True if decode fills out.irradiance itself.
  virtual bool decodesIrradiance() const { return false; }
};

// FP16 of every radiance value: 6 bytes per texel. Exact to FP16 rounding (relative 2^-11).
std::unique_ptr<ProbeCodec> makeRawFp16Codec();
// The raw FP16 payload with its low and high bytes split into two planes (byte shuffle, as Blosc does:
// exponent bytes compress far better together), then zstd at `level` in [1, 22]. Lossless w.r.t. FP16.
std::unique_ptr<ProbeCodec> makeZstdFp16Codec(int level);
// SH bands 0..lmax (lmax in [1, 7]; 2 = "SH L2", 9 coefficients; 7 = "SH L7", 64) per RGB channel,
// projected with the exact texel weights (core/sh_high_order.h), stored FP16. Decodes radiance at texel
// centres and irradiance by the cosine convolution.
std::unique_ptr<ProbeCodec> makeShCodec(int lmax);
// SH L1 as Unity's Adaptive Probe Volumes store it: L0 (the mean) per RGB channel in FP16, each of the 9 L1
// coefficients as its ratio to sqrt(3) L0 in int8 (the ratio of any non-negative radiance lies in [-1, 1]):
// 15 bytes per probe. Negative L0 (impossible for radiance >= 0, possible after float rounding) stores 0.
// Decodes as makeShCodec(1) does.
std::unique_ptr<ProbeCodec> makeShL1Q8Codec();
// PCA per cell: mean + k principal radiance maps of the cell's probes (LAPACK dsyevr on the Gram or the
// covariance matrix, whichever is smaller) + k coefficients per probe, all FP16. k is the smallest count
// whose discarded energy gives a radiance relative RMS <= errorTarget (before FP16 rounding), at most
// maxComponents. errorTarget in (0, 1], maxComponents in [1, 4096].
std::unique_ptr<ProbeCodec> makePcaCodec(double errorTarget, int maxComponents = 256);
// ASTC HDR (libastcenc, profile HDR RGB + LDR alpha) of each probe's radiance map, one block x block tile
// grid per probe (map padded by edge replication to a whole number of blocks: 16 bytes per block).
// block in {4, 5, 6, 8, 10, 12}; quality is astcenc's effort in [0, 100] (ASTCENC_PRE_FAST = 10,
// MEDIUM = 60, THOROUGH = 98).
std::unique_ptr<ProbeCodec> makeAstcHdrCodec(int block, float quality);

// field.irradiance from field.radiance: for each probe, each texel-centre normal of the m x m map gets
// bruteForceIrradiance (core/sh.h) of the probe's radiance map. Throws lfgi::Error if the radiance size
// disagrees with the grid and resolution.
void deriveIrradiance(ProbeField& field);

}  // namespace lfgi
