// A host engine's frame loop with lfgi embedded (docs/embedding.md): open a baked world, fly a scripted
// camera for N frames calling update() each frame, then sample the world's GI on a top-down grid of ground
// points and write it as a PNG. Exit 0 when every point is lit, 1 when one is not, 2 for bad arguments.
//   lfgi_example_host WORLD OUT.png [FRAMES]
// Only <lfgi/runtime.h> and the standard library: the PNG is written uncompressed (stored deflate).
#include <lfgi/runtime.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

namespace {

// ---- a minimal PNG writer (RGB8, zlib stored blocks) -----------------------------------------------------

uint32_t crc32(const uint8_t* p, size_t n, uint32_t crc = 0) {
  crc = ~crc;
  for (size_t i = 0; i < n; ++i) {
    crc ^= p[i];
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

void put32(std::vector<uint8_t>& v, uint32_t x) {
  for (int s = 24; s >= 0; s -= 8) v.push_back(uint8_t(x >> s));
}

void chunk(std::vector<uint8_t>& png, const char* type, const std::vector<uint8_t>& data) {
  put32(png, uint32_t(data.size()));
  std::vector<uint8_t> body(type, type + 4);
  body.insert(body.end(), data.begin(), data.end());
  png.insert(png.end(), body.begin(), body.end());
  put32(png, crc32(body.data(), body.size()));
}

bool writePng(const std::string& path, int w, int h, const std::vector<uint8_t>& rgb) {
  std::vector<uint8_t> raw;  // filter byte 0 per row
  for (int y = 0; y < h; ++y) {
    raw.push_back(0);
    raw.insert(raw.end(), rgb.begin() + size_t(y) * size_t(w) * 3,
               rgb.begin() + size_t(y + 1) * size_t(w) * 3);
  }
  std::vector<uint8_t> z = {0x78, 0x01};
  uint32_t a = 1, b = 0;
  for (uint8_t c : raw) a = (a + c) % 65521u, b = (b + a) % 65521u;
  size_t off = 0;
  do {  // stored (uncompressed) deflate blocks of at most 65535 bytes
    const size_t n = std::min<size_t>(65535, raw.size() - off);
    z.push_back(off + n == raw.size() ? 1 : 0);
    z.insert(z.end(), {uint8_t(n), uint8_t(n >> 8), uint8_t(~n), uint8_t(~n >> 8)});
    z.insert(z.end(), raw.begin() + std::ptrdiff_t(off), raw.begin() + std::ptrdiff_t(off + n));
    off += n;
  } while (off < raw.size());
  put32(z, (b << 16) | a);
  std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'}, ihdr;
  put32(ihdr, uint32_t(w)), put32(ihdr, uint32_t(h));
  ihdr.insert(ihdr.end(), {8, 2, 0, 0, 0});  // 8-bit RGB
  chunk(png, "IHDR", ihdr);
  chunk(png, "IDAT", z);
  chunk(png, "IEND", {});
  const std::string tmp = path + ".tmp";
  std::ofstream f(tmp, std::ios::binary);
  f.write(reinterpret_cast<const char*>(png.data()), std::streamsize(png.size()));
  f.close();
  return f && std::rename(tmp.c_str(), path.c_str()) == 0;
}

// ---- the host ----------------------------------------------------------------------------------------

// The camera of frame i: a circle at 40 % of the world's half size around its centre, 30 m up.
lfgi::Frame cameraAt(const lfgi::Runtime& rt, int i, float dt) {
  const float cx = 0.5f * rt.worldSizeX(), cz = 0.5f * rt.worldSizeZ(), r = 0.4f * std::min(cx, cz);
  const float t = float(i) * dt, w = 0.2f;  // rad/s
  lfgi::Frame f;
  f.position[0] = cx + r * std::cos(w * t), f.position[1] = 30.0f, f.position[2] = cz + r * std::sin(w * t);
  f.velocity[0] = -r * w * std::sin(w * t), f.velocity[2] = r * w * std::cos(w * t);
  const float speed = std::max(1e-6f, r * w);
  f.direction[0] = f.velocity[0] / speed, f.direction[2] = f.velocity[2] / speed;
  f.timeOfDayHours = 15.5f;
  f.dtSeconds = dt;
  return f;
}

uint8_t toByte(float linear) {
  const float tone = linear / (1.0f + linear);  // Reinhard, then display gamma
  return uint8_t(std::lround(255.0f * std::pow(std::clamp(tone, 0.0f, 1.0f), 1.0f / 2.2f)));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3 || argc > 4) {
    std::fprintf(stderr, "usage: lfgi_example_host WORLD OUT.png [FRAMES]\n");
    return 2;
  }
  const int frames = argc == 4 ? std::atoi(argv[3]) : 300;
  try {
    lfgi::RuntimeConfig config;
    config.world = argv[1];
    config.memoryBudgetBytes = size_t(64) << 20;
    const std::unique_ptr<lfgi::Runtime> rt = lfgi::Runtime::open(config);
    std::printf("lfgi %s: world %.0f x %.0f m, %.0f m cells\n", lfgi::runtimeVersion(), rt->worldSizeX(),
                rt->worldSizeZ(), rt->cellSize());
    // The frame loop: one update() per frame (the game thread), as a host's would be.
    double worstMs = 0.0;
    size_t peak = 0;
    lfgi::FrameReport last;
    for (int i = 0; i < frames; ++i) {
      last = rt->update(cameraAt(*rt, i, 1.0f / 30.0f));
      worstMs = std::max(worstMs, last.updateMs);
      peak = std::max(peak, last.bytesResident);
    }
    // GI on a top-down grid of ground points, 1 m up, normals up.
    const int w = 128, h = 128;
    std::vector<float> pos, nrm;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        pos.insert(pos.end(), {(float(x) + 0.5f) / float(w) * rt->worldSizeX(), 1.0f,
                               (float(y) + 0.5f) / float(h) * rt->worldSizeZ()});
        nrm.insert(nrm.end(), {0.0f, 1.0f, 0.0f});
      }
    std::vector<lfgi::GiSample> gi(size_t(w) * size_t(h));
    rt->sample(pos, nrm, gi);
    std::vector<uint8_t> rgb;
    int unlit = 0;
    for (const lfgi::GiSample& s : gi) {
      const float sum = s.irradiance[0] + s.irradiance[1] + s.irradiance[2];
      if (s.missing || !(sum > 0.0f) || !std::isfinite(sum)) ++unlit;
      for (float e : s.irradiance) rgb.push_back(toByte(e / 3.14159265f));
    }
    if (!writePng(argv[2], w, h, rgb)) {
      std::fprintf(stderr, "%s: cannot write the PNG\n", argv[2]);
      return 1;
    }
    std::printf(
        "%d frames: %d cells resident, peak %.1f MB of %.0f MB, worst update %.2f ms; %dx%d GI samples, %d "
        "unlit; wrote %s\n",
        frames, last.residentCells, double(peak) / 1048576.0, double(config.memoryBudgetBytes) / 1048576.0,
        worstMs, w, h, unlit, argv[2]);
    return unlit == 0 ? 0 : 1;
  } catch (const lfgi::RuntimeError& e) {
    std::fprintf(stderr, "lfgi: %s\n", e.what());
    return 1;
  }
}
