// Image: a float image with named channels, and its EXR (lossless, scene-referred) and PNG (tone-mapped,
// for eyes) files. Output images of the renderer, ground truth and error maps all go through this.
#pragma once

#include <cstddef>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lfgi {

struct Image {
  int width = 0;
  int height = 0;
  std::vector<std::string> channels;  // names, e.g. "R", "G", "B" or "indirect.R"; unique
  std::vector<float> pixels;          // interleaved, row-major, top row first: width*height*channels

  Image() = default;
  // Zero-filled image. Throws lfgi::Error if width or height < 0, a channel name is empty or repeated.
  Image(int w, int h, std::vector<std::string> channelNames);

  int channelCount() const { return static_cast<int>(channels.size()); }
  // Index of the channel called name, or -1.
  int channelIndex(std::string_view name) const;
  std::size_t offset(int x, int y, int c) const {
    return ((static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)) *
                channels.size() +
            static_cast<std::size_t>(c));
  }
  // Precondition: 0 <= x < width, 0 <= y < height, 0 <= c < channelCount().
  float& at(int x, int y, int c) { return pixels[offset(x, y, c)]; }
  float at(int x, int y, int c) const { return pixels[offset(x, y, c)]; }
  // All channels of pixel (x, y).
  std::span<float> pixel(int x, int y) { return {pixels.data() + offset(x, y, 0), channels.size()}; }
  std::span<const float> pixel(int x, int y) const {
    return {pixels.data() + offset(x, y, 0), channels.size()};
  }
  // Channel c of every pixel, copied out in pixel order.
  std::vector<float> channelValues(int c) const;
  // Throws lfgi::Error (naming `what`) unless width, height >= 1, there is at least one channel, names are
  // non-empty and unique, and pixels.size() == width * height * channels.
  void validate(std::string_view what) const;
};

// Writes all channels as 32-bit FLOAT (ZIP compression, lossless) to path via a temporary file, so a
// failed write leaves neither a partial file nor the temporary. The channel order is kept in the header
// attribute "lfgi.channelOrder" because OpenEXR itself lists channels alphabetically. Throws lfgi::Error
// "<path>: <problem>" on an invalid image or any I/O or library failure.
void writeExr(const std::filesystem::path& path, const Image& image);

// Reads every channel of a scanline or tiled EXR as float (HALF/UINT converted), the data window as the
// image. Channel order: as written by writeExr if the file has its "lfgi.channelOrder" attribute, else
// OpenEXR's alphabetical order. Throws lfgi::Error "<path>: <problem>" for a missing or unreadable file,
// a non-EXR file, truncated or corrupt data, deep data, subsampled channels, or a data window over 2^28
// pixels. A multi-part file gives its first part.
Image readExr(const std::filesystem::path& path);

enum class ToneMap {
  kAcesFitted,  // Narkowicz 2015, "ACES Filmic Tone Mapping Curve" (the fitted RRT+ODT curve)
  kReinhard,    // x / (1 + x), Reinhard et al. 2002
};

// Median Rec. 709 luminance of the layer's R, G, B channels (layer "" or e.g. "indirect."), at least
// 1e-12 (auto exposure: log2(0.18 / median)). Throws lfgi::Error for an empty image or a missing channel.
float medianLuminance(const Image& image, std::string_view layer = "");

// Writes an 8-bit sRGB PNG for viewing: linear value * 2^exposureEv, tone-mapped per channel, sRGB OETF
// (IEC 61966-2-1), rounded. Uses channels layer + "R", layer + "G", layer + "B" (layer "" or e.g.
// "indirect."); an image with exactly one channel and no such channels is written as grey. NaN writes
// as 0. Written via a temporary file (atomic). Throws lfgi::Error "<path>: <problem>".
void writePng(const std::filesystem::path& path, const Image& image, float exposureEv = 0.0f,
              ToneMap toneMap = ToneMap::kAcesFitted, std::string_view layer = "");

}  // namespace lfgi
