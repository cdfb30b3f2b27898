#include "core/image.h"

#include <ImfChannelList.h>
#include <ImfCompression.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStringVectorAttribute.h>
#include <ImfVersion.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <set>

// Static linkage so another library embedding stb_image_write cannot clash with this copy.
#define STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb/stb_image_write.h>

#include "core/error.h"
#include "core/file_util.h"

namespace lfgi {

namespace {

constexpr const char* kChannelOrderAttribute = "lfgi.channelOrder";
constexpr std::int64_t kMaxPixels = std::int64_t(1) << 28;
constexpr std::int64_t kMaxFloats = std::int64_t(1) << 30;

void checkChannelNames(const std::vector<std::string>& names, std::string_view what) {
  std::set<std::string_view> seen;
  for (const std::string& name : names) {
    if (name.empty()) fail("{}: empty channel name", what);
    if (!seen.insert(name).second) fail("{}: channel \"{}\" appears twice", what, name);
  }
}

// Narkowicz 2015 fit of the ACES RRT+ODT.
float acesFitted(float x) {
  const float y = (x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f);
  return std::clamp(y, 0.0f, 1.0f);
}

// IEC 61966-2-1 sRGB encoding of a value in [0, 1].
float srgbOetf(float v) {
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

std::uint8_t toDisplayByte(float linear, float scale, ToneMap toneMap) {
  float x = linear * scale;
  if (!(x > 0.0f)) return 0;  // also NaN
  x = toneMap == ToneMap::kAcesFitted ? acesFitted(x) : (std::isinf(x) ? 1.0f : x / (1.0f + x));
  return static_cast<std::uint8_t>(std::lround(std::clamp(srgbOetf(x), 0.0f, 1.0f) * 255.0f));
}

}  // namespace

Image::Image(int w, int h, std::vector<std::string> channelNames)
    : width(w), height(h), channels(std::move(channelNames)) {
  if (w < 0 || h < 0) fail("Image: size {} x {} is negative", w, h);
  checkChannelNames(channels, "Image");
  pixels.assign(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * channels.size(), 0.0f);
}

int Image::channelIndex(std::string_view name) const {
  for (std::size_t c = 0; c < channels.size(); ++c)
    if (channels[c] == name) return static_cast<int>(c);
  return -1;
}

std::vector<float> Image::channelValues(int c) const {
  std::vector<float> values(static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
  for (std::size_t i = 0; i < values.size(); ++i)
    values[i] = pixels[i * channels.size() + static_cast<std::size_t>(c)];
  return values;
}

void Image::validate(std::string_view what) const {
  if (width < 1 || height < 1) fail("{}: image size {} x {} is empty", what, width, height);
  if (channels.empty()) fail("{}: image has no channels", what);
  checkChannelNames(channels, what);
  const std::size_t expected =
      static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * channels.size();
  if (pixels.size() != expected)
    fail("{}: image has {} floats, expected {} for {} x {} x {} channels", what, pixels.size(), expected,
         width, height, channels.size());
}

void writeExr(const std::filesystem::path& path, const Image& image) {
  const std::string name = path.string();
  image.validate(name);
  writeViaTempFile(path, [&](const std::filesystem::path& tmp) {
    try {
      Imf::Header header(image.width, image.height);
      header.compression() = Imf::ZIP_COMPRESSION;
      header.insert(kChannelOrderAttribute, Imf::StringVectorAttribute(image.channels));
      Imf::FrameBuffer frameBuffer;
      const std::size_t xStride = image.channels.size() * sizeof(float);
      const std::size_t yStride = xStride * static_cast<std::size_t>(image.width);
      for (std::size_t c = 0; c < image.channels.size(); ++c) {
        header.channels().insert(image.channels[c], Imf::Channel(Imf::FLOAT));
        // OpenEXR wants a non-const base pointer for output slices too; it only reads through it.
        char* base = reinterpret_cast<char*>(const_cast<float*>(image.pixels.data() + c));
        frameBuffer.insert(image.channels[c], Imf::Slice(Imf::FLOAT, base, xStride, yStride));
      }
      Imf::OutputFile file(tmp.c_str(), header);
      file.setFrameBuffer(frameBuffer);
      file.writePixels(image.height);
    } catch (const Error&) {
      throw;
    } catch (const std::exception& e) {
      fail("{}: cannot write EXR ({})", name, e.what());
    }
  });
}

Image readExr(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(status)) fail("{}: file not found", name);
  if (!std::filesystem::is_regular_file(status)) fail("{}: not a regular file", name);
  {
    char magic[4] = {};
    std::ifstream in(path, std::ios::binary);
    if (!in) fail("{}: cannot open for reading", name);
    in.read(magic, sizeof magic);
    if (in.gcount() != sizeof magic || !Imf::isImfMagic(magic))
      fail("{}: not an OpenEXR file (no EXR magic number)", name);
  }
  try {
    Imf::InputFile file(name.c_str());
    const Imf::Header& header = file.header();
    const Imath::Box2i dataWindow = header.dataWindow();
    const std::int64_t w = std::int64_t(dataWindow.max.x) - dataWindow.min.x + 1;
    const std::int64_t h = std::int64_t(dataWindow.max.y) - dataWindow.min.y + 1;
    if (w < 1 || h < 1 || w * h > kMaxPixels) fail("{}: unsupported data window {} x {}", name, w, h);

    std::vector<std::string> names;
    for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
      if (it.channel().xSampling != 1 || it.channel().ySampling != 1)
        fail("{}: channel \"{}\" is subsampled, which is not supported", name, it.name());
      names.emplace_back(it.name());
    }
    if (names.empty()) fail("{}: EXR has no channels", name);
    if (w * h * std::int64_t(names.size()) > kMaxFloats)
      fail("{}: {} x {} x {} channels is too large", name, w, h, names.size());
    if (const auto* order = header.findTypedAttribute<Imf::StringVectorAttribute>(kChannelOrderAttribute)) {
      std::vector<std::string> sortedOrder = order->value();
      std::vector<std::string> sortedNames = names;
      std::sort(sortedOrder.begin(), sortedOrder.end());
      std::sort(sortedNames.begin(), sortedNames.end());
      if (sortedOrder == sortedNames) names = order->value();  // else stale: keep the file's order
    }

    Image image(static_cast<int>(w), static_cast<int>(h), names);
    Imf::FrameBuffer frameBuffer;
    const std::size_t xStride = names.size() * sizeof(float);
    const std::size_t yStride = xStride * static_cast<std::size_t>(w);
    for (std::size_t c = 0; c < names.size(); ++c) {
      frameBuffer.insert(names[c],
                         Imf::Slice::Make(Imf::FLOAT, image.pixels.data() + c, dataWindow, xStride, yStride));
    }
    file.setFrameBuffer(frameBuffer);
    if (!file.isComplete()) fail("{}: EXR is incomplete (truncated or missing scanlines)", name);
    file.readPixels(dataWindow.min.y, dataWindow.max.y);
    return image;
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    fail("{}: cannot read EXR ({})", name, e.what());
  }
}

void writePng(const std::filesystem::path& path, const Image& image, float exposureEv, ToneMap toneMap,
              std::string_view layer) {
  const std::string name = path.string();
  image.validate(name);
  int source[3];
  const char* suffix[3] = {"R", "G", "B"};
  for (int k = 0; k < 3; ++k) source[k] = image.channelIndex(std::string(layer) + suffix[k]);
  if (source[0] < 0 || source[1] < 0 || source[2] < 0) {
    if (image.channelCount() != 1)
      fail("{}: image has no channels {}R, {}G, {}B to write as PNG", name, layer, layer, layer);
    source[0] = source[1] = source[2] = 0;
  }
  if (!std::isfinite(exposureEv)) fail("{}: exposure {} EV is not finite", name, exposureEv);
  const float scale = std::exp2(exposureEv);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(image.width) *
                                  static_cast<std::size_t>(image.height) * 3);
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const std::size_t o = (static_cast<std::size_t>(y) * static_cast<std::size_t>(image.width) +
                             static_cast<std::size_t>(x)) *
                            3;
      for (int k = 0; k < 3; ++k)
        bytes[o + static_cast<std::size_t>(k)] = toDisplayByte(image.at(x, y, source[k]), scale, toneMap);
    }
  }
  writeViaTempFile(path, [&](const std::filesystem::path& tmp) {
    if (stbi_write_png(tmp.c_str(), image.width, image.height, 3, bytes.data(), image.width * 3) == 0)
      fail("{}: cannot write PNG", name);
  });
}

float medianLuminance(const Image& image, std::string_view layer) {
  const std::string l(layer);
  const int r = image.channelIndex(l + "R"), g = image.channelIndex(l + "G"), b = image.channelIndex(l + "B");
  if (r < 0 || g < 0 || b < 0) fail("medianLuminance: the image has no {}R, {}G, {}B channels", l, l, l);
  if (image.width <= 0 || image.height <= 0) fail("medianLuminance: empty image");
  std::vector<float> lum;
  lum.reserve(size_t(image.width) * size_t(image.height));
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x)
      lum.push_back(0.2126f * image.at(x, y, r) + 0.7152f * image.at(x, y, g) + 0.0722f * image.at(x, y, b));
  std::nth_element(lum.begin(), lum.begin() + long(lum.size() / 2), lum.end());
  return std::max(lum[lum.size() / 2], 1e-12f);
}

}  // namespace lfgi
