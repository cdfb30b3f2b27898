#include "streaming/cell_source.h"

#include <chrono>
#include <cmath>
#include <thread>

#include "core/error.h"
#include "core/octahedral.h"

namespace lfgi::streaming {

float WorldLayout::distanceToCell(glm::vec3 p, glm::ivec2 c) const {
  glm::vec2 lo = cellMin(c), hi = lo + cellSize, q(p.x, p.z);
  glm::vec2 d = glm::max(glm::max(lo - q, q - hi), glm::vec2(0.0f));
  return glm::length(d);
}

namespace {

constexpr glm::vec3 kTint{1.0f, 0.9f, 0.8f};

float base(glm::vec3 p) {
  return 1.0f + 0.5f * std::sin(p.x / 37.0f) * std::cos(p.z / 53.0f) + 0.02f * p.y;
}

// Radiance L(w) = (a + b w.y) whose irradiance is E(n) = pi a + (2 pi / 3) b n.y = B (1 + 0.5 n.y).
glm::vec3 radianceFor(float B, glm::vec3 w) {
  const float pi = 3.14159265358979f;
  float a = B / pi, b = 0.75f * B / pi;
  return kTint * (a + b * w.y);
}

}  // namespace

glm::vec3 SyntheticCellSource::exactIrradiance(glm::vec3 p, glm::vec3 n) {
  return kTint * base(p) * (1.0f + 0.5f * n.y);
}

SyntheticCellSource::SyntheticCellSource(SyntheticSourceOptions options) : options_(std::move(options)) {
  const WorldLayout& l = options_.layout;
  if (!(l.cellSize > 0.0f) || l.cells.x < 1 || l.cells.y < 1) fail("SyntheticCellSource: bad world layout");
  float perAxis = l.cellSize / options_.probeSpacing;
  if (!(options_.probeSpacing > 0.0f) || perAxis != std::floor(perAxis))
    fail("SyntheticCellSource: probe spacing {} m does not divide the {} m cell", options_.probeSpacing,
         l.cellSize);
  if (options_.layers < 1 || options_.resolution < 1 || options_.irradianceResolution < 1)
    fail("SyntheticCellSource: layers and resolutions must be >= 1");
  ProbeField probe;
  probe.grid.dims = {int(perAxis), options_.layers, int(perAxis)};
  probe.resolution = options_.resolution;
  probe.irradianceResolution = options_.irradianceResolution;
  size_t P = size_t(probe.grid.probeCount()), n2 = size_t(options_.resolution * options_.resolution),
         m2 = size_t(options_.irradianceResolution * options_.irradianceResolution);
  cellBytes_ = sizeof(float) * P * (n2 * 3 + n2 * 2 + m2 * 3);
}

ShL1 SyntheticCellSource::fallback(glm::ivec2 cell) const {
  const WorldLayout& l = options_.layout;
  glm::vec2 c = l.cellMin(cell) + 0.5f * l.cellSize;
  float B = base({c.x, 0.5f + 0.5f * options_.probeSpacing * float(options_.layers - 1), c.y});
  constexpr int n = 8;
  std::vector<float> map(size_t(n * n * 3));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      glm::vec3 L = radianceFor(B, octTexelDirection(i, j, n));
      for (int k = 0; k < 3; ++k) map[size_t((j * n + i) * 3 + k)] = L[k];
    }
  return shProject<4>(map, n);
}

void SyntheticCellSource::load(glm::ivec2 cell, ProbeField& out) {
  fill(cell, out, timeOfDay_.load());
  loads_.fetch_add(1);
}

void SyntheticCellSource::relightInto(glm::ivec2 cell, const ProbeField& /*current*/, ProbeField& out,
                                      float timeOfDayHours) {
  fill(cell, out, timeOfDayHours);
  relights_.fetch_add(1);
}

void SyntheticCellSource::fill(glm::ivec2 cell, ProbeField& out, float hours) const {
  const float scale = timeOfDayScale(hours);
  const WorldLayout& l = options_.layout;
  if (!l.contains(cell)) fail("cell {},{}: outside the {}x{} world", cell.x, cell.y, l.cells.x, l.cells.y);
  if (options_.loadDelayUs > 0) std::this_thread::sleep_for(std::chrono::microseconds(options_.loadDelayUs));
  if (options_.corruptCells.count({cell.x, cell.y}))
    fail("cell_{}_{}.lfc: content hash mismatch (synthetic corrupt cell)", cell.x, cell.y);
  glm::vec2 lo = l.cellMin(cell);
  const int perAxis = int(l.cellSize / options_.probeSpacing);
  out.grid.origin = {lo.x, 0.5f, lo.y};
  out.grid.spacing = glm::vec3(options_.probeSpacing);
  out.grid.dims = {perAxis, options_.layers, perAxis};
  out.resolution = options_.resolution;
  out.irradianceResolution = options_.irradianceResolution;
  out.offsets.clear();
  out.active.clear();
  out.normal.clear();
  out.albedo.clear();
  const size_t P = size_t(out.grid.probeCount());
  const int n = out.resolution, m = out.irradianceResolution;
  out.radiance.resize(P * size_t(n * n * 3));
  out.distance.resize(P * size_t(n * n * 2));
  out.irradiance.resize(P * size_t(m * m * 3));
  for (size_t p = 0; p < P; ++p) {
    glm::vec3 pos = out.grid.probePosition(out.grid.probeCoord(int64_t(p)));
    float B = base(pos) * scale;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        size_t t = p * size_t(n * n) + size_t(j * n + i);
        glm::vec3 L = radianceFor(B, octTexelDirection(i, j, n));
        for (int k = 0; k < 3; ++k) out.radiance[t * 3 + size_t(k)] = L[k];
        out.distance[t * 2] = 10.0f;
        out.distance[t * 2 + 1] = 100.0f;
      }
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) {
        glm::vec3 E = scale * exactIrradiance(pos, octTexelDirection(i, j, m));
        size_t t = p * size_t(m * m) + size_t(j * m + i);
        for (int k = 0; k < 3; ++k) out.irradiance[t * 3 + size_t(k)] = E[k];
      }
  }
}

}  // namespace lfgi::streaming
