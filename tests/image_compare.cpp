// lfgi_image_compare REF.exr LAYER TEST.pfm MAX_REL_RMS: the relative RMS of TEST (a PFM, RGB) against
// the channels LAYER.R/G/B of REF (an EXR, e.g. `lfgi render`'s indirect_diffuse), over every pixel.
// Prints it; exit 0 when it is <= MAX_REL_RMS, 1 when above or on any error (named), 2 for bad usage.
// Used by tests/example_host.sh to hold the example host's image to `lfgi render` of the same view.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/image.h"

namespace {

// RGB floats, top row first. Throws lfgi::Error naming the file.
std::vector<float> readPfm(const std::string& path, int& w, int& h) {
  std::ifstream f(path, std::ios::binary);
  std::string magic;
  float scale = 0.0f;
  if (!(f >> magic >> w >> h >> scale) || magic != "PF" || w < 1 || h < 1 || w > 16384 || h > 16384 ||
      scale >= 0.0f)
    lfgi::fail("{}: not a little-endian RGB PFM", path);
  f.get();
  std::vector<float> rows(size_t(w) * size_t(h) * 3), out(rows.size());
  if (!f.read(reinterpret_cast<char*>(rows.data()), std::streamsize(rows.size() * sizeof(float))))
    lfgi::fail("{}: truncated ({}x{} pixels expected)", path, w, h);
  const size_t row = size_t(w) * 3;
  for (int y = 0; y < h; ++y)  // PFM rows run bottom to top
    std::copy_n(rows.data() + size_t(h - 1 - y) * row, row, out.data() + size_t(y) * row);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 5) {
    std::fprintf(stderr, "usage: lfgi_image_compare REF.exr LAYER TEST.pfm MAX_REL_RMS\n");
    return 2;
  }
  try {
    const lfgi::Image ref = lfgi::readExr(argv[1]);
    int w = 0, h = 0;
    const std::vector<float> test = readPfm(argv[3], w, h);
    if (w != ref.width || h != ref.height)
      lfgi::fail("{} is {}x{}, {} is {}x{}", argv[3], w, h, argv[1], ref.width, ref.height);
    const std::string layer = argv[2];
    int c[3];
    for (int k = 0; k < 3; ++k) {
      c[k] = ref.channelIndex(layer + "." + "RGB"[k]);
      if (c[k] < 0) lfgi::fail("{}: no channel {}.{}", argv[1], layer, "RGB"[k]);
    }
    double err = 0.0, norm = 0.0, sumTest = 0.0, sumRef = 0.0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int k = 0; k < 3; ++k) {
          const double a = test[(size_t(y) * size_t(w) + size_t(x)) * 3 + size_t(k)], b = ref.at(x, y, c[k]);
          if (!std::isfinite(a)) lfgi::fail("{}: pixel {},{} is not finite", argv[3], x, y);
          err += (a - b) * (a - b);
          sumTest += a;
          sumRef += b;
          norm += b * b;
        }
    const double rel = norm > 0.0 ? std::sqrt(err / norm) : std::sqrt(err);
    const double limit = std::atof(argv[4]);
    std::printf("%s vs %s %s: relative RMS %.5f (limit %.5f), mean ratio %.4f\n", argv[3], argv[1],
                layer.c_str(), rel, limit, sumRef > 0.0 ? sumTest / sumRef : 0.0);
    return rel <= limit ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lfgi_image_compare: %s\n", e.what());
    return 1;
  }
}
