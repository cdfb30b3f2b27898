// lfgi_http_check: a baked world streamed from an HTTP server (streaming/http_region_source.h) against the
// same world on disk; tests/http_serving.sh runs it against nginx on 127.0.0.1.
//   lfgi_http_check same WORLD_DIR URL     every cell over HTTP is the disk cell: same state, and its load
//                                           (radiance, irradiance, distance) bit-identical
//   lfgi_http_check dropped URL COMMAND    opens the world, runs COMMAND (stops the server), then every load
//                                           must fail with an lfgi::Error naming the URL while the cells'
//                                           fallbacks stay what they were
//   lfgi_http_check truncated URL X,Z      cell X,Z's region file is served short: that cell alone is
//                                           corrupt, with an error naming its URL and the cell
//   lfgi_http_check runtime WORLD_DIR URL  lfgi::Runtime with VIR visibility opened on the URL samples
//                                           the same GI as on the directory, bit for bit, from decoded cells
// Prints what it checked; exit 0 when it holds, 1 otherwise (named), 2 for bad usage.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "core/error.h"
#include "lfgi/runtime.h"
#include "streaming/cell_file_source.h"

namespace {

using namespace lfgi;
using streaming::CellFileSource;
using streaming::CellFileSourceOptions;
using streaming::CellFileState;
using streaming::WorldLayout;

CellFileSourceOptions urlOptions(const std::string& url) {
  CellFileSourceOptions o;
  o.worldUrl = url;
  return o;
}

bool sameFloats(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
}

int same(const std::string& dir, const std::string& url) {
  CellFileSourceOptions d;
  d.worldDir = dir;
  d.storage = streaming::CellStorage::Regions;
  CellFileSource disk(d), http(urlOptions(url));
  const WorldLayout l = disk.layout();
  int loaded = 0;
  for (int z = 0; z < l.cells.y; ++z)
    for (int x = 0; x < l.cells.x; ++x) {
      if (disk.info({x, z}).state != http.info({x, z}).state)
        fail("cell {},{}: state differs over HTTP", x, z);
      if (disk.info({x, z}).state != CellFileState::Valid) continue;
      ProbeField a, b;
      disk.load({x, z}, a);
      http.load({x, z}, b);
      if (!sameFloats(a.radiance, b.radiance) || !sameFloats(a.irradiance, b.irradiance) ||
          !sameFloats(a.distance, b.distance))
        fail("cell {},{}: the field loaded over HTTP differs from the disk's", x, z);
      ++loaded;
    }
  std::printf("same: %d cells loaded over HTTP from %s, bit-identical to %s\n", loaded,
              http.store().location().c_str(), disk.store().location().c_str());
  return loaded > 0 ? 0 : 1;
}

int dropped(const std::string& url, const std::string& command) {
  CellFileSource http(urlOptions(url));
  const WorldLayout l = http.layout();
  std::vector<ShL1> before;
  for (int z = 0; z < l.cells.y; ++z)
    for (int x = 0; x < l.cells.x; ++x) before.push_back(http.fallback({x, z}));
  if (std::system(command.c_str()) != 0) fail("dropped: '{}' failed", command);
  int failed = 0;
  std::string example;
  for (int z = 0; z < l.cells.y; ++z)
    for (int x = 0; x < l.cells.x; ++x) {
      if (http.info({x, z}).state != CellFileState::Valid) continue;
      try {
        ProbeField f;
        http.load({x, z}, f);
      } catch (const Error& e) {
        if (std::string(e.what()).find(url) == std::string::npos)
          fail("dropped: error without the URL: {}", e.what());
        if (example.empty()) example = e.what();  // the first: the one the command cut short
        ++failed;
        continue;
      }
      fail("dropped: cell {},{} loaded with the server stopped", x, z);
    }
  for (int z = 0, i = 0; z < l.cells.y; ++z)
    for (int x = 0; x < l.cells.x; ++x, ++i)
      for (int k = 0; k < 4; ++k)
        if (http.fallback({x, z}).c[size_t(k)] != before[size_t(i)].c[size_t(k)])
          fail("dropped: cell {},{}'s fallback changed", x, z);
  std::printf("dropped: %d loads failed cleanly, fallbacks kept; the first: %s\n", failed, example.c_str());
  return failed > 0 ? 0 : 1;
}

int truncated(const std::string& url, int cx, int cz) {
  CellFileSource http(urlOptions(url));
  const auto& inf = http.info({cx, cz});
  if (inf.state != CellFileState::Corrupt) fail("truncated: cell {},{} is not corrupt", cx, cz);
  if (inf.error.find(url) == std::string::npos ||
      inf.error.find(fmt::format("cell ({}, {})", cx, cz)) == std::string::npos)
    fail("truncated: the error does not name the URL and the cell: {}", inf.error);
  std::printf("truncated: %d valid, %d corrupt; %s\n", http.validCells(), http.corruptCells(),
              inf.error.c_str());
  return 0;
}

// Every cell resident and faded in: the camera over the world's middle, 64 one-second frames, loads inline.
std::vector<lfgi::GiSample> runtimeSamples(const std::string& world, std::vector<float>& points) {
  lfgi::RuntimeConfig c;
  c.world = world;
  c.ioThreads = 0;
  c.activateBudgetMs = 1e6;
  c.decodeRadius = 1e5f;  // the whole (small) test world
  c.keepRadius = 2e5f;
  std::unique_ptr<lfgi::Runtime> rt = lfgi::Runtime::open(c);
  const float sx = rt->worldSizeX(), sz = rt->worldSizeZ();
  lfgi::Frame f;
  f.position[0] = 0.5f * sx, f.position[1] = 20.0f, f.position[2] = 0.5f * sz;
  f.dtSeconds = 1.0f;
  for (int i = 0; i < 64; ++i) rt->update(f);
  const int n = 24;  // a grid of points 1.5 m up, normals up, then sideways
  points.clear();
  std::vector<float> normals;
  for (int k = 0; k < 2; ++k)
    for (int z = 0; z < n; ++z)
      for (int x = 0; x < n; ++x) {
        points.insert(points.end(), {(float(x) + 0.5f) * sx / n, 1.5f, (float(z) + 0.5f) * sz / n});
        normals.insert(normals.end(), {0.0f, k == 0 ? 1.0f : 0.0f, k == 0 ? 0.0f : 1.0f});
      }
  std::vector<lfgi::GiSample> out(points.size() / 3);
  rt->sample(points, normals, out);
  return out;
}

int runtime(const std::string& dir, const std::string& url) {
  std::vector<float> points;
  const std::vector<lfgi::GiSample> disk = runtimeSamples(dir, points), http = runtimeSamples(url, points);
  int decoded = 0;
  for (size_t i = 0; i < disk.size(); ++i) {
    if (std::memcmp(disk[i].irradiance, http[i].irradiance, sizeof(disk[i].irradiance)) != 0 ||
        disk[i].fallbackWeight != http[i].fallbackWeight || disk[i].missing != http[i].missing)
      fail("runtime: the sample at ({}, {}, {}) differs over HTTP", points[3 * i], points[3 * i + 1],
           points[3 * i + 2]);
    if (disk[i].missing) fail("runtime: no light at ({}, {})", points[3 * i], points[3 * i + 2]);
    decoded += disk[i].fallbackWeight == 0.0f;
  }
  std::printf(
      "runtime: %zu samples with VIR visibility over HTTP bit-identical to disk, %d from decoded cells\n",
      disk.size(), decoded);
  return decoded > 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  spdlog::set_level(spdlog::level::err);
  const std::string mode = argc > 1 ? argv[1] : "";
  try {
    if (mode == "same" && argc == 4) return same(argv[2], argv[3]);
    if (mode == "dropped" && argc == 4) return dropped(argv[2], argv[3]);
    if (mode == "runtime" && argc == 4) return runtime(argv[2], argv[3]);
    int x = 0, z = 0;
    if (mode == "truncated" && argc == 4 && std::sscanf(argv[3], "%d,%d", &x, &z) == 2)
      return truncated(argv[2], x, z);
  } catch (const std::exception& e) {  // lfgi::Error, lfgi::RuntimeError
    std::fprintf(stderr, "lfgi_http_check: %s\n", e.what());
    return 1;
  }
  std::fprintf(
      stderr,
      "usage: lfgi_http_check same WORLD_DIR URL | dropped URL COMMAND | truncated URL X,Z | runtime "
      "WORLD_DIR URL\n");
  return 2;
}
