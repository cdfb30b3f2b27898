#include "worlds/synthetic_world.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include <fmt/format.h>

#include "core/error.h"
#include "core/hash.h"

// Layout of this file: hashing and noise; the world's pure functions (cell kinds, roads, terrain); the
// CellBuilder that emits boxes into the mesh and the descriptors at once; the building generator; block
// layouts (towers, courtyard, arcade, leak test, houses, park, field); SyntheticWorld's members.

namespace lfgi::worlds {
namespace {

// ---------------------------------------------------------------------------------------------------
// Counter-based randomness: splitmix64 (core/hash.h) applied to a key built from (seed, purpose,
// integers...). No state is shared between cells, so any cell can be generated alone.

inline uint64_t hashKey(uint64_t key) {
  return key;
}
template <typename... Rest>
uint64_t hashKey(uint64_t key, int64_t first, Rest... rest) {
  return hashKey(splitmix64(key ^ splitmix64(uint64_t(first) + 0x632be59bd9b4e019ull)), int64_t(rest)...);
}

// What a random number is for; part of every key so streams for different purposes never correlate.
// Values are part of the world's definition: changing one changes every world.
enum Purpose : int64_t {
  kPurposeUrbanLow = 1,
  kPurposeUrbanHigh = 2,
  kPurposeUrbanJitter = 3,
  kPurposePark = 4,
  kPurposeBlockType = 5,
  kPurposeHill = 6,  // octave o uses kPurposeHill + 16 * o
  kPurposeBlock = 7,
  kPurposeField = 9,
  kPurposeEdit = 10,  // world edits (world_edits.h): keyed by edit index
};

// A stream of numbers from one key: value i is splitmix64(key + i * golden). Used inside one object's
// generation, whose code runs in a fixed order, so the stream is reproducible.
class Rng {
 public:
  explicit Rng(uint64_t key) : key_(key) {}
  uint64_t next() { return splitmix64(key_ + kGoldenGamma * ++counter_); }
  double u01() { return unitDouble(next()); }
  double range(double lo, double hi) { return lo + (hi - lo) * u01(); }
  int irange(int lo, int hi) { return lo + int(next() % uint64_t(hi - lo + 1)); }  // inclusive
  bool chance(double p) { return u01() < p; }
  Rng child(int64_t index) const { return Rng(hashKey(key_, index)); }

 private:
  uint64_t key_;
  uint64_t counter_ = 0;
};

int64_t floorDiv(int64_t a, int64_t b) {
  return a / b - ((a % b != 0) && ((a < 0) != (b < 0)));
}

double fade(double t) {
  return t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
}  // quintic (Perlin 2002)

// Value noise in [0, 1): hashed values on the integer lattice, quintic interpolation.
double valueNoise(uint64_t seed, int64_t purpose, double x, double z) {
  const double fx0 = std::floor(x), fz0 = std::floor(z);
  const int64_t ix = int64_t(fx0), iz = int64_t(fz0);
  const double tx = fade(x - fx0), tz = fade(z - fz0);
  auto v = [&](int64_t a, int64_t b) { return unitDouble(hashKey(seed, purpose, a, b)); };
  const double a = v(ix, iz) + (v(ix + 1, iz) - v(ix, iz)) * tx;
  const double b = v(ix, iz + 1) + (v(ix + 1, iz + 1) - v(ix, iz + 1)) * tx;
  return a + (b - a) * tz;
}

double smoothstep01(double t) {
  if (t <= 0.0) return 0.0;
  if (t >= 1.0) return 1.0;
  return t * t * (3.0 - 2.0 * t);
}

bool isUrban(CellKind k) {
  return k != CellKind::kField;
}

// ---------------------------------------------------------------------------------------------------
// World constants (metres).

constexpr double kMainHalfWidth = 6.0;    // main roads are 12 m wide
constexpr double kStreetHalfWidth = 4.0;  // streets are 8 m wide
constexpr double kSidewalk = 2.5;         // between road edge and building lot
constexpr double kHillAmplitude = 30.0;
constexpr double kMinUrbanCell = 32.0;
constexpr double kBlockTarget = 64.0;  // target block pitch: cells of >= 96 m get inner streets

// The showcase district: the first 4×4 cells of every world (see the header).
constexpr CellKind F = CellKind::kField, S = CellKind::kSuburb, C = CellKind::kCity, P = CellKind::kPark;
constexpr CellKind kShowcaseKinds[4][4] = {
    // [z][x]
    {F, S, S, F},
    {S, C, C, P},
    {F, C, C, S},
    {F, F, S, F},
};
constexpr BlockType kShowcaseBlocks[4][4] = {
    {BlockType::kNone, BlockType::kHouses, BlockType::kHouses, BlockType::kNone},
    {BlockType::kHouses, BlockType::kLeakTest, BlockType::kArcade, BlockType::kPark},
    {BlockType::kNone, BlockType::kCourtyard, BlockType::kTowers, BlockType::kHouses},
    {BlockType::kNone, BlockType::kNone, BlockType::kHouses, BlockType::kNone},
};

struct Rect {
  double x0 = 0, z0 = 0, x1 = 0, z1 = 0;
  double w() const { return x1 - x0; }
  double d() const { return z1 - z0; }
  bool containsHalfOpen(double x, double z) const { return x >= x0 && x < x1 && z >= z0 && z < z1; }
  Rect shrunk(double m) const { return {x0 + m, z0 + m, x1 - m, z1 - m}; }
  double distance(double x, double z) const {
    const double dx = std::max({x0 - x, 0.0, x - x1});
    const double dz = std::max({z0 - z, 0.0, z - z1});
    return std::sqrt(dx * dx + dz * dz);
  }
};

// The world's pure functions of (params, integers). Every cell evaluates shared data through these, so
// two cells agree bit for bit.
struct WorldView {
  uint64_t seed;
  double cellM;
  int cells;
  int quads;        // terrain lattice quads per cell edge
  int mainSpacing;  // main road every mainSpacing cell lines

  double stepM() const { return cellM / double(quads); }
  double cellOrigin(int64_t c) const { return double(c) * cellM; }
  bool inWorld(int64_t cx, int64_t cz) const { return cx >= 0 && cz >= 0 && cx < cells && cz < cells; }
  bool showcase(int64_t cx, int64_t cz) const {
    return cells >= 4 && cellM >= kMinUrbanCell && cx < 4 && cz < 4;
  }
  int blocksPerCell() const { return std::max(1, int(std::floor(cellM / kBlockTarget + 0.5))); }

  CellKind kindAt(int64_t cx, int64_t cz) const {
    if (!inWorld(cx, cz) || cellM < kMinUrbanCell) return CellKind::kField;
    if (showcase(cx, cz)) return kShowcaseKinds[cz][cx];
    // Urbanness: low-frequency value noise over the cell centre (towns of a few hundred metres), plus a
    // per-cell jitter so district edges are ragged.
    const double xm = (double(cx) + 0.5) * cellM, zm = (double(cz) + 0.5) * cellM;
    const double u = 0.65 * valueNoise(seed, kPurposeUrbanLow, xm / 900.0, zm / 900.0) +
                     0.35 * valueNoise(seed, kPurposeUrbanHigh, xm / 350.0, zm / 350.0) +
                     0.14 * (unitDouble(hashKey(seed, kPurposeUrbanJitter, cx, cz)) - 0.5);
    if (u > 0.585)
      return unitDouble(hashKey(seed, kPurposePark, cx, cz)) < 0.1 ? CellKind::kPark : CellKind::kCity;
    if (u > 0.5) return CellKind::kSuburb;
    return CellKind::kField;
  }

  BlockType blockAt(int64_t cx, int64_t cz, int bi, int bj) const {
    switch (kindAt(cx, cz)) {
      case CellKind::kField:
        return BlockType::kNone;
      case CellKind::kSuburb:
        return BlockType::kHouses;
      case CellKind::kPark:
        return BlockType::kPark;
      case CellKind::kCity:
        break;
    }
    if (showcase(cx, cz)) return kShowcaseBlocks[cz][cx];
    const double r = unitDouble(hashKey(seed, kPurposeBlockType, cx, cz, bi, bj));
    if (r < 0.14) return BlockType::kCourtyard;
    if (r < 0.28) return BlockType::kArcade;
    if (r < 0.40) return BlockType::kLeakTest;
    return BlockType::kTowers;
  }

  // Road lines: line e is x = e * cellM (vertical) or z = e * cellM (horizontal).
  bool mainLine(int64_t e) const { return e > 0 && e < cells && e % mainSpacing == 0; }
  double lineHalfWidth(int64_t e) const { return mainLine(e) ? kMainHalfWidth : kStreetHalfWidth; }
  // Segment of vertical line e along cell row c (between cells (e-1, c) and (e, c)), or of horizontal
  // line e along cell column c (between (c, e-1) and (c, e)). No roads on the world boundary.
  bool segmentHasRoad(bool vertical, int64_t e, int64_t c) const {
    if (e <= 0 || e >= cells || c < 0 || c >= cells) return false;
    if (mainLine(e)) return true;
    return vertical ? (isUrban(kindAt(e - 1, c)) || isUrban(kindAt(e, c)))
                    : (isUrban(kindAt(c, e - 1)) || isUrban(kindAt(c, e)));
  }

  // Road rectangles of a cell (they may overlap at corners): half strips along its edges, and full inner
  // streets in urban cells with several blocks. All edges are cut exactly on the cell border.
  void roadRects(int64_t cx, int64_t cz, std::vector<Rect>& out) const {
    out.clear();
    if (!inWorld(cx, cz)) return;
    const double x0 = cellOrigin(cx), x1 = cellOrigin(cx + 1), z0 = cellOrigin(cz), z1 = cellOrigin(cz + 1);
    if (segmentHasRoad(true, cx, cz)) out.push_back({x0, z0, x0 + lineHalfWidth(cx), z1});
    if (segmentHasRoad(true, cx + 1, cz)) out.push_back({x1 - lineHalfWidth(cx + 1), z0, x1, z1});
    if (segmentHasRoad(false, cz, cx)) out.push_back({x0, z0, x1, z0 + lineHalfWidth(cz)});
    if (segmentHasRoad(false, cz + 1, cx)) out.push_back({x0, z1 - lineHalfWidth(cz + 1), x1, z1});
    const int nb = blocksPerCell();
    if (nb > 1 && isUrban(kindAt(cx, cz))) {
      for (int k = 1; k < nb; ++k) {
        const double xk = x0 + double(k) * cellM / double(nb), zk = z0 + double(k) * cellM / double(nb);
        out.push_back({xk - kStreetHalfWidth, z0, xk + kStreetHalfWidth, z1});
        out.push_back({x0, zk - kStreetHalfWidth, x1, zk + kStreetHalfWidth});
      }
    }
  }

  bool isRoad(double x, double z) const {
    const int64_t cx = int64_t(std::floor(x / cellM)), cz = int64_t(std::floor(z / cellM));
    if (!inWorld(cx, cz)) return false;
    std::vector<Rect> rects;
    roadRects(cx, cz, rects);
    for (const Rect& r : rects)
      if (r.containsHalfOpen(x, z)) return true;
    return false;
  }

  // ---- terrain ----
  // Lattice coordinate of global index i: cell origin plus whole steps, so index c * quads is exactly the
  // cell border c * cellM whichever cell asks.
  double latticeCoord(int64_t i) const {
    const int64_t c = floorDiv(i, quads);
    return cellOrigin(c) + double(i - c * quads) * stepM();
  }

  double hillField(double x, double z) const {
    // fBm of value noise, 5 octaves from 420 m down to 26 m.
    double sum = 0.0, norm = 0.0, amp = 1.0, wavelength = 420.0;
    for (int o = 0; o < 5; ++o) {
      sum += amp * valueNoise(seed, kPurposeHill + 16 * o, x / wavelength, z / wavelength);
      norm += amp;
      amp *= 0.5;
      wavelength *= 0.5;
    }
    const double n = sum / norm;
    return kHillAmplitude * smoothstep01((n - 0.32) / 0.45);
  }

  // 0 on and near roads and urban cells (flat ground at y = 0), rising to 1 over `ramp` metres.
  double hillWeight(double x, double z) const {
    const double step = stepM();
    // Flat at least one lattice step (plus lamp/prop room) beyond every road edge, so the terrain triangles
    // under a road, a lamp or a building are exactly flat.
    const double margin = step + 2.0;
    const double ramp =
        cellM >= kMinUrbanCell ? std::clamp(cellM - kStreetHalfWidth - margin - 1.0, 4.0, 40.0) : 40.0;
    double d = std::numeric_limits<double>::infinity();
    const double linePitch = cellM * double(mainSpacing);
    for (double p : {x, z}) {
      const int64_t k = int64_t(std::floor(p / linePitch + 0.5));
      for (int64_t kk = k - 1; kk <= k + 1; ++kk) {
        const int64_t e = kk * mainSpacing;
        if (mainLine(e)) d = std::min(d, std::abs(p - cellOrigin(e)) - kMainHalfWidth);
      }
    }
    // Urban cells: streets run along their edges, so flatten out to the street's far side. The ramp fits
    // inside one cell, so the 3×3 neighbourhood is enough.
    const int64_t cx = int64_t(std::floor(x / cellM)), cz = int64_t(std::floor(z / cellM));
    for (int64_t dz = -1; dz <= 1; ++dz)
      for (int64_t dx = -1; dx <= 1; ++dx) {
        if (!isUrban(kindAt(cx + dx, cz + dz))) continue;
        const Rect r{cellOrigin(cx + dx), cellOrigin(cz + dz), cellOrigin(cx + dx + 1),
                     cellOrigin(cz + dz + 1)};
        d = std::min(d, r.distance(x, z) - kStreetHalfWidth);
      }
    return smoothstep01((d - margin) / ramp);
  }

  // Height of lattice point (ix, iz): the one function every cell uses for terrain vertices.
  float latticeHeight(int64_t ix, int64_t iz) const {
    const double x = latticeCoord(ix), z = latticeCoord(iz);
    const double w = hillWeight(x, z);
    if (w <= 0.0) return 0.0f;
    return float(w * hillField(x, z));
  }

  int64_t latticeIndexBelow(double p) const {
    int64_t i = int64_t(std::floor(p / stepM()));
    while (latticeCoord(i) > p) --i;
    while (latticeCoord(i + 1) <= p) ++i;
    return i;
  }

  float terrainHeight(double x, double z) const {
    const int64_t i = latticeIndexBelow(x), j = latticeIndexBelow(z);
    const double xa = latticeCoord(i), xb = latticeCoord(i + 1), za = latticeCoord(j),
                 zb = latticeCoord(j + 1);
    const double fx = (x - xa) / (xb - xa), fz = (z - za) / (zb - za);
    // Same split as the mesh: diagonal from (i, j+1) to (i+1, j).
    if (fx + fz <= 1.0) {
      const double h00 = latticeHeight(i, j), h10 = latticeHeight(i + 1, j), h01 = latticeHeight(i, j + 1);
      return float(h00 + fx * (h10 - h00) + fz * (h01 - h00));
    }
    const double h11 = latticeHeight(i + 1, j + 1), h10 = latticeHeight(i + 1, j),
                 h01 = latticeHeight(i, j + 1);
    return float(h11 + (1.0 - fx) * (h01 - h11) + (1.0 - fz) * (h10 - h11));
  }
};

// ---------------------------------------------------------------------------------------------------
// Materials. Albedo is linear; emission in scene units (radiance).

struct MatSpec {
  std::string name;
  glm::vec3 albedo{0.5f};
  glm::vec3 emission{0.0f};
  SurfaceCategory category = SurfaceCategory::kWall;
  bool doubleSided = false;
};

MatSpec mat(std::string name, glm::vec3 albedo, SurfaceCategory cat) {
  MatSpec m;
  m.name = std::move(name);
  m.albedo = albedo;
  m.category = cat;
  return m;
}

const glm::vec3 kLampRadiance{80.0f, 64.0f, 40.0f};  // warm sodium-ish street lamp
const glm::vec3 kWindowRadiance{3.0f, 2.4f, 1.5f};   // lit window at night: modest
const glm::vec3 kRed{0.75f, 0.05f, 0.04f}, kGreen{0.06f, 0.6f, 0.08f}, kBlue{0.05f, 0.1f, 0.72f};

MatSpec interiorMat() {
  return mat("interior_plaster", {0.7f, 0.68f, 0.64f}, SurfaceCategory::kInterior);
}
MatSpec slabMat() {
  return mat("interior_slab", {0.55f, 0.52f, 0.48f}, SurfaceCategory::kInterior);
}
MatSpec roofMat() {
  return mat("roof", {0.3f, 0.28f, 0.27f}, SurfaceCategory::kRoof);
}
MatSpec propMat(std::string name, glm::vec3 albedo) {
  return mat(std::move(name), albedo, SurfaceCategory::kProp);
}
MatSpec glassMat() {
  MatSpec m = mat("glass", {0.08f, 0.1f, 0.12f}, SurfaceCategory::kGlass);
  m.doubleSided = true;
  return m;
}
MatSpec litWindowMat() {
  MatSpec m = mat("lit_window", {0.8f, 0.75f, 0.6f}, SurfaceCategory::kEmissive);
  m.emission = kWindowRadiance;
  m.doubleSided = true;
  return m;
}
MatSpec lampHeadMat() {
  MatSpec m = mat("lamp_head", {0.9f, 0.9f, 0.85f}, SurfaceCategory::kEmissive);
  m.emission = kLampRadiance;
  return m;
}

MatSpec facadeMat(glm::vec3 albedo) {
  return mat(fmt::format("facade_{:.3f}_{:.3f}_{:.3f}", albedo.r, albedo.g, albedo.b), albedo,
             SurfaceCategory::kWall);
}

glm::vec3 neutralFacade(Rng& rng) {
  static const glm::vec3 kPalette[] = {{0.45f, 0.44f, 0.42f}, {0.42f, 0.2f, 0.14f},  {0.6f, 0.5f, 0.35f},
                                       {0.75f, 0.74f, 0.7f},  {0.35f, 0.38f, 0.42f}, {0.55f, 0.4f, 0.3f}};
  return kPalette[rng.irange(0, 5)];
}
glm::vec3 saturatedFacade(Rng& rng) {
  switch (rng.irange(0, 2)) {
    case 0:
      return kRed;
    case 1:
      return kGreen;
    default:
      return kBlue;
  }
}
bool isSaturated(glm::vec3 a) {
  const float mx = std::max({a.r, a.g, a.b}), mn = std::min({a.r, a.g, a.b});
  return mx >= 0.5f && mn <= 0.12f * mx + 1e-6f;
}

// ---------------------------------------------------------------------------------------------------
// CellBuilder: every primitive goes to the mesh (when there is one) and to the descriptors together, so
// describeCell and generateCell cannot disagree.

class CellBuilder {
 public:
  CellBuilder(TriangleMesh* mesh, CellLayout& layout) : mesh_(mesh), layout_(layout) {}

  CellLayout& layout() { return layout_; }
  // XZ regions of clear-region / add-building edits over this cell: generated buildings and props whose
  // extent overlaps one (positive area) are not emitted (world_edits.h).
  void setClears(std::vector<Rect> clears) { clears_ = std::move(clears); }
  bool cleared(const Rect& r) const {
    for (const Rect& c : clears_)
      if (r.x0 < c.x1 && c.x0 < r.x1 && r.z0 < c.z1 && c.z0 < r.z1) return true;
    return false;
  }
  bool hasMesh() const { return mesh_ != nullptr; }
  TriangleMesh* mesh() { return mesh_; }

  uint32_t material(const MatSpec& m) {
    if (!mesh_) return 0;
    for (size_t i = 0; i < mesh_->materials.size(); ++i)
      if (mesh_->materials[i].name == m.name) return uint32_t(i);
    Material out;
    out.name = m.name;
    out.albedo = m.albedo;
    out.emission = m.emission;
    out.category = m.category;
    out.doubleSided = m.doubleSided;
    return mesh_->addMaterial(out);
  }

  // A solid axis-aligned box; returns its float AABB.
  Aabb box(glm::dvec3 lo, glm::dvec3 hi, const MatSpec& m) {
    const glm::vec3 l(lo), h(hi);
    const Aabb b{glm::min(l, h), glm::max(l, h)};
    if (b.max.x <= b.min.x || b.max.y <= b.min.y || b.max.z <= b.min.z) return b;  // degenerate: skip
    if (mesh_) mesh_->addBox(b.min, b.max, material(m));
    layout_.solids.push_back({b, m.category});
    maxY_ = std::max(maxY_, b.max.y);
    return b;
  }

  // A solid box whose faces have their own materials, in TriangleMesh::addBox's face order (-Z, +Z, -X,
  // +X, +Y, -Y); the solid's category is `solid`'s.
  Aabb boxFaces(glm::dvec3 lo, glm::dvec3 hi, const std::array<const MatSpec*, 6>& faces,
                const MatSpec& solid) {
    const glm::vec3 l(lo), h(hi);
    const Aabb b{glm::min(l, h), glm::max(l, h)};
    if (b.max.x <= b.min.x || b.max.y <= b.min.y || b.max.z <= b.min.z) return b;
    if (mesh_) {
      const glm::vec3 a = b.min, c = b.max;
      const glm::vec3 p[8] = {{a.x, a.y, a.z}, {c.x, a.y, a.z}, {c.x, c.y, a.z}, {a.x, c.y, a.z},
                              {a.x, a.y, c.z}, {c.x, a.y, c.z}, {c.x, c.y, c.z}, {a.x, c.y, c.z}};
      mesh_->addQuad(p[1], p[0], p[3], p[2], material(*faces[0]));
      mesh_->addQuad(p[4], p[5], p[6], p[7], material(*faces[1]));
      mesh_->addQuad(p[0], p[4], p[7], p[3], material(*faces[2]));
      mesh_->addQuad(p[5], p[1], p[2], p[6], material(*faces[3]));
      mesh_->addQuad(p[3], p[7], p[6], p[2], material(*faces[4]));
      mesh_->addQuad(p[0], p[1], p[5], p[4], material(*faces[5]));
    }
    layout_.solids.push_back({b, solid.category});
    maxY_ = std::max(maxY_, b.max.y);
    return b;
  }

  // A planar quad, wound so its front faces `normal`.
  void quad(glm::dvec3 a, glm::dvec3 b, glm::dvec3 c, glm::dvec3 d, glm::dvec3 normal, const MatSpec& m) {
    maxY_ = std::max({maxY_, float(a.y), float(b.y), float(c.y), float(d.y)});
    if (!mesh_) return;
    if (glm::dot(glm::cross(b - a, c - a), normal) < 0.0) std::swap(b, d);
    mesh_->addQuad(glm::vec3(a), glm::vec3(b), glm::vec3(c), glm::vec3(d), material(m));
  }

  float maxY() const { return maxY_; }

 private:
  TriangleMesh* mesh_;
  CellLayout& layout_;
  float maxY_ = 0.0f;
  std::vector<Rect> clears_;
};

Aabb makeAabb(glm::dvec3 a, glm::dvec3 b) {
  const glm::vec3 fa(a), fb(b);
  return Aabb{glm::min(fa, fb), glm::max(fa, fb)};
}

// A 2D rectangle [s0, s1] × [t0, t1] minus rectangular holes, cut into few rectangles: horizontal bands at
// every hole edge, solid intervals per band, and identical intervals of consecutive bands merged. A facade
// with one row of windows per storey becomes one spandrel per storey plus the piers between windows.
struct Rect2 {
  double s0, s1, t0, t1;
};
std::vector<Rect2> subtractHoles(const Rect2& outer, const std::vector<Rect2>& holes) {
  std::vector<double> ts{outer.t0, outer.t1};
  for (const Rect2& h : holes) {
    if (h.t0 > outer.t0 && h.t0 < outer.t1) ts.push_back(h.t0);
    if (h.t1 > outer.t0 && h.t1 < outer.t1) ts.push_back(h.t1);
  }
  std::sort(ts.begin(), ts.end());
  ts.erase(std::unique(ts.begin(), ts.end()), ts.end());
  std::vector<Rect2> done, active;
  for (size_t b = 0; b + 1 < ts.size(); ++b) {
    const double ta = ts[b], tb = ts[b + 1];
    std::vector<std::pair<double, double>> cuts;
    for (const Rect2& h : holes)
      if (h.t0 <= ta && h.t1 >= tb && h.s1 > outer.s0 && h.s0 < outer.s1) cuts.push_back({h.s0, h.s1});
    std::sort(cuts.begin(), cuts.end());
    std::vector<std::pair<double, double>> solid;
    double s = outer.s0;
    for (const auto& [c0, c1] : cuts) {
      if (c0 > s) solid.push_back({s, c0});
      s = std::max(s, c1);
    }
    if (s < outer.s1) solid.push_back({s, outer.s1});
    std::vector<Rect2> next;
    for (const auto& [a, c] : solid) {
      if (c - a < 1e-6) continue;
      // Init-captures: clang 14 (the fuzz build) cannot capture structured bindings by reference.
      auto it = std::find_if(active.begin(), active.end(),
                             [a = a, c = c](const Rect2& r) { return r.s0 == a && r.s1 == c; });
      if (it != active.end()) {
        Rect2 r = *it;
        r.t1 = tb;
        next.push_back(r);
        active.erase(it);
      } else {
        next.push_back({a, c, ta, tb});
      }
    }
    done.insert(done.end(), active.begin(), active.end());
    active = std::move(next);
  }
  done.insert(done.end(), active.begin(), active.end());
  return done;
}

// Building-local frame: u along the long axis, v across, y up. uAlongX: (u, v) -> (x, z) = o + (u, v);
// else (u, v) -> o + (v, u). Axis swaps keep boxes boxes.
struct Frame {
  double ox = 0, oz = 0;
  bool uAlongX = true;
  glm::dvec3 p(double u, double y, double v) const {
    return uAlongX ? glm::dvec3(ox + u, y, oz + v) : glm::dvec3(ox + v, y, oz + u);
  }
  glm::dvec3 dirU() const { return uAlongX ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 0, 1); }
  glm::dvec3 dirV() const { return uAlongX ? glm::dvec3(0, 0, 1) : glm::dvec3(1, 0, 0); }
  Aabb aabb(double u0, double u1, double v0, double v1, double y0, double y1) const {
    return makeAabb(p(u0, y0, v0), p(u1, y1, v1));
  }
  Aabb box(CellBuilder& b, double u0, double u1, double v0, double v1, double y0, double y1,
           const MatSpec& m) const {
    return b.box(p(u0, y0, v0), p(u1, y1, v1), m);
  }
};

// ---------------------------------------------------------------------------------------------------
// Buildings.

enum class Fill : uint8_t { kOpen, kGlass, kLit };

struct WindowStyle {
  double bay = 3.4;    // target window pitch along a facade
  double width = 1.5;  // window width (narrower where a span is small)
  double sill = 0.9;   // above the storey's floor
  double head = 2.3;
  double glazedP = 0.5;  // chance the building's windows are glazed (else open holes)
  double litP = 0.1;     // chance a window is lit (emissive pane)
};

struct BuildingPlan {
  Frame f;
  double L = 10, D = 10;  // extent along u and v
  int storeys = 1;
  double storeyH = 3.0;
  double base = 0.15;  // top of the ground-floor slab
  double extT = 0.3, intT = 0.15, slabT = 0.25;
  WindowStyle win;
  RoofKind roof = RoofKind::kFlatParapet;
  double overhang = 0.0;
  double parapet = 0.8;
  bool corridor = false;
  int entrance = 0;                   // facade side with the ground-floor entrance door; -1 none
  std::array<glm::vec3, 4> facade{};  // albedo per side: 0 (v = 0), 1 (v = D), 2 (u = 0), 3 (u = L)
  std::array<std::vector<std::pair<double, double>>, 4> blocked;  // s-intervals without openings
  int arcadeSide = -1;  // 0 or 1: colonnade outside that facade, ground-floor high
  double arcadeDepth = 3.0;
  bool courtyardWing = false;
  bool forceLit = true;  // at least one lit window if the building has windows
  bool edit = false;     // from an add-building edit: not subject to the cell's clear regions
};

// XZ extent of everything a plan emits (footprint, roof overhang, arcade).
Rect planExtent(const BuildingPlan& bp) {
  double u0 = 0.0, u1 = bp.L, v0 = 0.0, v1 = bp.D;
  if (bp.roof == RoofKind::kFlatOverhang) {
    u0 -= bp.overhang;
    u1 += bp.overhang;
    v0 -= bp.overhang;
    v1 += bp.overhang;
  }
  if (bp.arcadeSide == 0 && bp.storeys >= 2) v0 = std::min(v0, -bp.arcadeDepth - 0.25);
  if (bp.arcadeSide == 1 && bp.storeys >= 2) v1 = std::max(v1, bp.D + bp.arcadeDepth + 0.25);
  const glm::dvec3 a = bp.f.p(u0, 0.0, v0), b = bp.f.p(u1, 0.0, v1);
  return {std::min(a.x, b.x), std::min(a.z, b.z), std::max(a.x, b.x), std::max(a.z, b.z)};
}

struct Opening {
  int side = -1;          // 0..3 facade, or -1 interior
  double s0 = 0, s1 = 0;  // along the wall
  double y0 = 0, y1 = 0;
  Fill fill = Fill::kOpen;
  bool door = false;
  bool interior = false;
  glm::dvec2 probeA{0}, probeB{0};  // local (u, v) points on either side (B: interior openings only)
};
Opening makeOpening(int side, double s0, double s1, double y0, double y1, Fill fill, bool door) {
  Opening o;
  o.side = side;
  o.s0 = s0;
  o.s1 = s1;
  o.y0 = y0;
  o.y1 = y1;
  o.fill = fill;
  o.door = door;
  return o;
}

struct LocalRoom {
  double u0 = 0, u1 = 0, v0 = 0, v1 = 0, y0 = 0, y1 = 0;
  int storey = 0;
  bool corridor = false;
  int openings = 0, glazed = 0;
  bool contains(double u, double v, double y) const {
    return u > u0 && u < u1 && v > v0 && v < v1 && y > y0 && y < y1;
  }
};
LocalRoom makeRoom(double u0, double u1, double v0, double v1, double y0, double y1, int storey,
                   bool corridor) {
  LocalRoom r;
  r.u0 = u0;
  r.u1 = u1;
  r.v0 = v0;
  r.v1 = v1;
  r.y0 = y0;
  r.y1 = y1;
  r.storey = storey;
  r.corridor = corridor;
  return r;
}

// Evenly spaced windows in the span [a, b]: one per `bay` metres, centred in equal sub-spans.
std::vector<std::pair<double, double>> placeWindows(double a, double b, double bay, double width) {
  std::vector<std::pair<double, double>> out;
  const double len = b - a;
  const int n = std::max(1, int(std::floor(len / bay + 1e-9)));
  const double sub = len / double(n);
  const double w = std::min(width, sub - 0.8);
  if (w < 0.6) return out;
  for (int i = 0; i < n; ++i) {
    const double c = a + (double(i) + 0.5) * sub;
    out.push_back({c - 0.5 * w, c + 0.5 * w});
  }
  return out;
}

bool overlapsAny(double s0, double s1, const std::vector<std::pair<double, double>>& iv) {
  for (const auto& [a, b] : iv)
    if (s1 > a && s0 < b) return true;
  return false;
}

// Index of a box face (addBox order: -Z, +Z, -X, +X, +Y, -Y) for an axis direction.
int faceIndex(glm::dvec3 d) {
  if (d.z < -0.5) return 0;
  if (d.z > 0.5) return 1;
  if (d.x < -0.5) return 2;
  if (d.x > 0.5) return 3;
  return d.y > 0.5 ? 4 : 5;
}

// Exterior wall of facade `side` (0: v = 0, 1: v = D, 2: u = 0, 3: u = L) of a building L × D with walls
// t thick, from wallBot to wallTop, minus `holes` (s along the wall, y). Sides 0/1 run the full length, 2/3
// fit between them. Up to `roofTop` the face towards the rooms is interior plaster (so paint does not
// bleed indoors); the parapet band above it is painted all round.
void emitExteriorWall(CellBuilder& cb, const Frame& f, int side, double L, double D, double t, double wallBot,
                      double roofTop, double wallTop, const std::vector<Rect2>& holes, const MatSpec& paint) {
  const double s0 = side < 2 ? 0.0 : t, s1 = side < 2 ? L : D - t;
  const std::array<glm::dvec3, 4> outward{-f.dirV(), f.dirV(), -f.dirU(), f.dirU()};
  const MatSpec plaster = interiorMat();
  std::array<const MatSpec*, 6> faces{&paint, &paint, &paint, &paint, &paint, &paint};
  auto emit = [&](const Rect2& r) {
    const glm::dvec3 lo = side == 0   ? f.p(r.s0, r.t0, 0)
                          : side == 1 ? f.p(r.s0, r.t0, D - t)
                          : side == 2 ? f.p(0, r.t0, r.s0)
                                      : f.p(L - t, r.t0, r.s0);
    const glm::dvec3 hi = side == 0   ? f.p(r.s1, r.t1, t)
                          : side == 1 ? f.p(r.s1, r.t1, D)
                          : side == 2 ? f.p(t, r.t1, r.s1)
                                      : f.p(L, r.t1, r.s1);
    cb.boxFaces(lo, hi, faces, paint);
  };
  const double split = std::min(roofTop, wallTop);
  faces[size_t(faceIndex(-outward[size_t(side)]))] = &plaster;
  for (const Rect2& r : subtractHoles({s0, s1, wallBot, split}, holes)) emit(r);
  faces[size_t(faceIndex(-outward[size_t(side)]))] = &paint;
  if (wallTop > split) emit({s0, s1, split, wallTop});
}

// One building's emission from its plan, stage by stage; the members are the plan's dimensions and what
// each stage hands to the next.
struct BuildingEmitter {
  BuildingEmitter(CellBuilder& builder, const BuildingPlan& plan) : cb(builder), bp(plan) {}

  void planRooms(Rng& rng);
  void placeOpenings(Rng& rng);
  void emitExteriorWalls();
  void emitFloors();
  void emitRoof();
  void emitArcade();
  int record();

  CellBuilder& cb;
  const BuildingPlan& bp;
  CellLayout& lay = cb.layout();
  const Frame& f = bp.f;
  const double L = bp.L, D = bp.D, t = bp.extT, it = bp.intT, h = bp.storeyH, st = bp.slabT;
  const int n = bp.storeys;
  const double top = bp.base + double(n) * h;
  const double wallTop = bp.roof == RoofKind::kFlatParapet ? top + bp.parapet : top - st;
  const double wallBot = bp.base - st;
  const MatSpec inMat = interiorMat(), slab = slabMat();
  const std::array<glm::dvec3, 4> outward{-f.dirV(), f.dirV(), -f.dirU(), f.dirU()};

  // Plan (planRooms).
  std::vector<double> dividers;                  // wall centre lines along u
  std::vector<std::pair<double, double>> roomU;  // air ranges
  const bool corridor = bp.corridor && D >= 10.0;
  const double cw = 1.8;
  const double vc0 = 0.5 * D - 0.5 * cw, vc1 = 0.5 * D + 0.5 * cw;  // corridor air
  std::vector<std::pair<double, double>> roomV;                     // air ranges across v
  std::vector<std::pair<double, double>> endSpans;                  // window spans on the end walls
  std::vector<LocalRoom> rooms;

  std::vector<Opening> openings;  // exterior (placeOpenings), then interior doors (emitFloors)
  Aabb roofBox;
  Arcade arcade;
  bool hasArcade = false;
};

void BuildingEmitter::planRooms(Rng& rng) {
  // --- plan: rooms along u (bays grouped 1 or 2 per room), optional central corridor along u.
  const double Li = L - 2 * t;
  const int nbay = std::max(1, int(std::floor(Li / bp.win.bay + 1e-9)));
  const double bw = Li / double(nbay);
  {
    int j = 0;
    while (j < nbay) {
      const int k = (bw < 3.0 || rng.chance(0.3)) ? 2 : 1;
      j = std::min(nbay, j + k);
      if (j < nbay) dividers.push_back(t + double(j) * bw);
    }
  }
  {
    double a = t;
    for (double dc : dividers) {
      roomU.push_back({a, dc - 0.5 * it});
      a = dc + 0.5 * it;
    }
    roomU.push_back({a, L - t});
  }
  if (corridor)
    roomV = {{t, vc0 - it}, {vc1 + it, D - t}};
  else
    roomV = {{t, D - t}};
  endSpans = roomV;
  if (corridor) endSpans.insert(endSpans.begin() + 1, {vc0, vc1});

  for (int k = 0; k < n; ++k) {
    const double yf = bp.base + double(k) * h, yc = yf + h - st;
    for (const auto& [v0, v1] : roomV)
      for (const auto& [u0, u1] : roomU) rooms.push_back(makeRoom(u0, u1, v0, v1, yf, yc, k, false));
    if (corridor) rooms.push_back(makeRoom(t, L - t, vc0, vc1, yf, yc, k, true));
  }
}

void BuildingEmitter::placeOpenings(Rng& rng) {
  // --- exterior openings
  bool glazed = rng.chance(bp.win.glazedP);
  auto fillFor = [&](Rng& r) {
    return r.chance(bp.win.litP) ? Fill::kLit : (glazed ? Fill::kGlass : Fill::kOpen);
  };
  for (int side = 0; side < 4; ++side) {
    const std::vector<std::pair<double, double>>& spans = side < 2 ? roomU : endSpans;
    for (int k = 0; k < n; ++k) {
      const double yf = bp.base + double(k) * h;
      const bool shop = k == 0 && side == bp.arcadeSide;
      const double sill = shop ? 0.35 : bp.win.sill;
      const double head = shop ? std::min(2.6, h - st - 0.15) : bp.win.head;
      for (size_t si = 0; si < spans.size(); ++si) {
        const auto [a, b] = spans[si];
        const bool door =
            k == 0 && side == bp.entrance && si == (side < 2 ? spans.size() / 2 : (corridor ? 1u : 0u));
        if (door) {
          const double w = std::min(1.4, b - a - 0.6);
          const double c = 0.5 * (a + b);
          if (w >= 0.8 && !overlapsAny(c - 0.5 * w, c + 0.5 * w, bp.blocked[side])) {
            openings.push_back(makeOpening(side, c - 0.5 * w, c + 0.5 * w, yf, yf + 2.3, Fill::kOpen, true));
            continue;
          }
        }
        for (const auto& [s0, s1] : placeWindows(a, b, shop ? 2.6 : bp.win.bay, shop ? 2.2 : bp.win.width)) {
          if (overlapsAny(s0, s1, bp.blocked[side])) continue;
          openings.push_back(makeOpening(side, s0, s1, yf + sill, yf + head, fillFor(rng), false));
        }
      }
    }
  }
  if (bp.forceLit) {
    std::vector<size_t> windows;
    bool anyLit = false;
    for (size_t i = 0; i < openings.size(); ++i) {
      if (!openings[i].door) windows.push_back(i);
      anyLit = anyLit || openings[i].fill == Fill::kLit;
    }
    if (!anyLit && !windows.empty()) openings[windows[rng.next() % windows.size()]].fill = Fill::kLit;
  }
  // Inner probe points (just inside the wall) for room bookkeeping.
  for (Opening& o : openings) {
    const double c = 0.5 * (o.s0 + o.s1);
    switch (o.side) {
      case 0:
        o.probeA = {c, t + 0.05};
        break;
      case 1:
        o.probeA = {c, D - t - 0.05};
        break;
      case 2:
        o.probeA = {t + 0.05, c};
        break;
      default:
        o.probeA = {L - t - 0.05, c};
        break;
    }
  }
}

void BuildingEmitter::emitExteriorWalls() {
  // --- exterior walls: sides 0/1 run the full length, 2/3 fit between them.
  for (int side = 0; side < 4; ++side) {
    const MatSpec m = facadeMat(bp.facade[size_t(side)]);
    const double s0 = side < 2 ? 0.0 : t, s1 = side < 2 ? L : D - t;
    std::vector<Rect2> holes;
    for (const Opening& o : openings)
      if (o.side == side) holes.push_back({o.s0, o.s1, o.y0, o.y1});
    emitExteriorWall(cb, f, side, L, D, t, wallBot, top, wallTop, holes, m);
    // Panes in the wall's mid-plane.
    for (const Opening& o : openings) {
      if (o.side != side || o.fill == Fill::kOpen) continue;
      const double mid = side == 0 ? 0.5 * t : side == 1 ? D - 0.5 * t : side == 2 ? 0.5 * t : L - 0.5 * t;
      auto at = [&](double s, double y) { return side < 2 ? f.p(s, y, mid) : f.p(mid, y, s); };
      const MatSpec pm = o.fill == Fill::kLit ? litWindowMat() : glassMat();
      cb.quad(at(o.s0, o.y0), at(o.s1, o.y0), at(o.s1, o.y1), at(o.s0, o.y1), outward[size_t(side)], pm);
      if (o.fill == Fill::kLit) {
        Emitter e;
        e.kind = EmitterKind::kLitWindow;
        e.box = makeAabb(at(o.s0, o.y0), at(o.s1, o.y1));
        e.normal = glm::vec3(outward[size_t(side)]);
        e.radiance = kWindowRadiance;
        e.areaM2 = float((o.s1 - o.s0) * (o.y1 - o.y0));
        lay.emitters.push_back(e);
      }
    }
    if (isSaturated(bp.facade[size_t(side)])) {
      ColouredWall painted;
      const double face = side == 0 ? 0.0 : side == 1 ? D : side == 2 ? 0.0 : L;
      painted.box = side < 2 ? f.aabb(s0, s1, face, face, wallBot, wallTop)
                             : f.aabb(face, face, s0, s1, wallBot, wallTop);
      painted.albedo = bp.facade[size_t(side)];
      painted.normal = glm::vec3(outward[size_t(side)]);
      lay.colouredWalls.push_back(painted);
    }
  }
}

void BuildingEmitter::emitFloors() {
  // --- slabs, interior walls with doors
  for (int k = 0; k < n; ++k) {
    const double yf = bp.base + double(k) * h, yc = yf + h - st;
    f.box(cb, t, L - t, t, D - t, yf - st, yf, slab);
    const double doorH = std::min(2.1, yc - yf - 0.2);
    if (corridor) {
      for (int wall = 0; wall < 2; ++wall) {
        const double va = wall == 0 ? vc0 - it : vc1, vb = va + it;
        std::vector<Rect2> holes;
        for (const auto& [u0, u1] : roomU) {
          if (u1 - u0 < 1.3) continue;
          const double c = 0.5 * (u0 + u1);
          holes.push_back({c - 0.45, c + 0.45, yf, yf + doorH});
          Opening o = makeOpening(-1, c - 0.45, c + 0.45, yf, yf + doorH, Fill::kOpen, true);
          o.interior = true;
          o.probeA = {c, va - 0.05};
          o.probeB = {c, vb + 0.05};
          openings.push_back(o);
        }
        for (const Rect2& r : subtractHoles({t, L - t, yf, yc}, holes))
          f.box(cb, r.s0, r.s1, va, vb, r.t0, r.t1, inMat);
      }
      for (double dc : dividers) {
        f.box(cb, dc - 0.5 * it, dc + 0.5 * it, t, vc0 - it, yf, yc, inMat);
        f.box(cb, dc - 0.5 * it, dc + 0.5 * it, vc1 + it, D - t, yf, yc, inMat);
      }
    } else {
      for (double dc : dividers) {
        const double c = 0.5 * D;
        std::vector<Rect2> holes{{c - 0.45, c + 0.45, yf, yf + doorH}};
        Opening o = makeOpening(-1, c - 0.45, c + 0.45, yf, yf + doorH, Fill::kOpen, true);
        o.interior = true;
        o.probeA = {dc - 0.5 * it - 0.05, c};
        o.probeB = {dc + 0.5 * it + 0.05, c};
        openings.push_back(o);
        for (const Rect2& r : subtractHoles({t, D - t, yf, yc}, holes))
          f.box(cb, dc - 0.5 * it, dc + 0.5 * it, r.s0, r.s1, r.t0, r.t1, inMat);
      }
    }
  }
}

void BuildingEmitter::emitRoof() {
  // --- roof
  const MatSpec rm = roofMat();
  if (bp.roof == RoofKind::kFlatParapet) {
    roofBox = f.box(cb, t, L - t, t, D - t, top - st, top, rm);
  } else {
    const double e = bp.overhang;
    roofBox = f.box(cb, -e, L + e, -e, D + e, top - st, top, rm);
  }
}

void BuildingEmitter::emitArcade() {
  // --- arcade: pillars and a roof slab at the first-floor level, outside facade arcadeSide.
  if (bp.arcadeSide >= 0 && n >= 2) {
    const double ad = bp.arcadeDepth;
    const double vOut = bp.arcadeSide == 0 ? -ad - 0.25 : D + ad + 0.25;  // outer edge of the roof
    const double vIn = bp.arcadeSide == 0 ? 0.0 : D;
    const double ry0 = bp.base + h - st, ry1 = bp.base + h;
    arcade.roof = f.box(cb, 0, L, std::min(vIn, vOut), std::max(vIn, vOut), ry0, ry1,
                        propMat("arcade_roof", {0.6f, 0.58f, 0.55f}));
    const int np = std::max(1, int(std::lround((L - 0.6) / 3.6)));
    const double pv0 = bp.arcadeSide == 0 ? -ad - 0.15 : D + ad - 0.25;  // pillar v range
    const MatSpec pm = propMat("pillar", {0.7f, 0.68f, 0.62f});
    for (int j = 0; j <= np; ++j) {
      const double uc = 0.3 + double(j) * (L - 0.6) / double(np);
      f.box(cb, uc - 0.2, uc + 0.2, pv0, pv0 + 0.4, wallBot, ry0, pm);
    }
    arcade.pillars = np + 1;
    const double wv0 = bp.arcadeSide == 0 ? -ad + 0.25 : D, wv1 = bp.arcadeSide == 0 ? 0.0 : D + ad - 0.25;
    arcade.walkway = f.aabb(0, L, wv0, wv1, 0.0, ry0);
    arcade.outwardNormal = glm::vec3(outward[size_t(bp.arcadeSide)]);
    arcade.building = int(lay.buildings.size());
    hasArcade = true;
  }
}

// Counts each room's openings and appends the building and its rooms to the layout; returns its index.
int BuildingEmitter::record() {
  // --- rooms: openings from probe points.
  for (const Opening& o : openings) {
    const double y = 0.5 * (o.y0 + o.y1);
    for (LocalRoom& r : rooms) {
      const bool hitA = r.contains(o.probeA.x, o.probeA.y, y);
      const bool hitB = o.interior && r.contains(o.probeB.x, o.probeB.y, y);
      if (!hitA && !hitB) continue;
      if (o.fill == Fill::kOpen)
        ++r.openings;
      else
        ++r.glazed;
    }
  }
  Building bld;
  bld.footprint = f.aabb(0, L, 0, D, wallBot, std::max(wallTop, top));
  bld.bounds = bld.footprint;
  bld.bounds.extend(roofBox);
  if (hasArcade) bld.bounds.extend(arcade.roof);
  bld.storeys = n;
  bld.storeyHeightM = float(h);
  bld.groundFloorY = float(bp.base);
  bld.wallThicknessM = float(t);
  bld.roof = bp.roof;
  bld.overhangM = bp.roof == RoofKind::kFlatOverhang ? float(bp.overhang) : 0.0f;
  bld.firstRoom = int(lay.rooms.size());
  bld.roomCount = int(rooms.size());
  bld.hasArcade = hasArcade;
  bld.isCourtyardWing = bp.courtyardWing;
  const int index = int(lay.buildings.size());
  for (const LocalRoom& r : rooms) {
    Room out;
    out.air = f.aabb(r.u0, r.u1, r.v0, r.v1, r.y0, r.y1);
    out.building = index;
    out.storey = r.storey;
    out.openings = r.openings;
    out.glazedWindows = r.glazed;
    out.corridor = r.corridor;
    out.sealed = r.openings == 0 && r.glazed == 0;
    lay.rooms.push_back(out);
  }
  lay.buildings.push_back(bld);
  if (hasArcade) lay.arcades.push_back(arcade);
  return index;
}

// Emits one building from its plan; returns its index in layout.buildings, or -1 when a clear region
// removed it (nothing emitted; the caller's random stream is unchanged either way).
int emitBuilding(CellBuilder& cb, const BuildingPlan& bp, Rng rng) {
  if (!bp.edit && cb.cleared(planExtent(bp))) return -1;
  BuildingEmitter b(cb, bp);
  b.planRooms(rng);
  b.placeOpenings(rng);
  b.emitExteriorWalls();
  b.emitFloors();
  b.emitRoof();
  b.emitArcade();
  return b.record();
}

// The leak-test house: one storey, lit room | thin partition | sealed room. The lit room has a big
// unglazed opening in facade `front` (0: v = 0, 1: v = D) and a skylight next to the partition, so it is
// sunlit for any sun above the horizon on the street side or high in the sky; the sealed room has no
// opening of any kind.
int emitLeakHouse(CellBuilder& cb, const Frame& f, double L, double D, int front, glm::vec3 facade, Rng rng) {
  {
    const Aabb e = f.aabb(0, L, 0, D, 0, 0);
    if (cb.cleared({e.min.x, e.min.z, e.max.x, e.max.z})) return -1;
  }
  CellLayout& lay = cb.layout();
  const double t = 0.3, st = 0.25, h = 3.2, base = 0.15, parapet = 0.6;
  const double tw = 0.1 + 0.05 * double(rng.irange(0, 2));  // 0.10, 0.15 or 0.20
  const double m = 0.5 * L;                                 // partition centre
  const double top = base + h, wallTop = top + parapet, wallBot = base - st, yc = top - st;
  const MatSpec wm = facadeMat(facade);
  const MatSpec im = interiorMat();
  // Opening of the lit room in the front facade.
  const double os0 = t + 0.5, os1 = m - 0.5 * tw - 0.5, oy0 = base + 0.4, oy1 = yc - 0.3;
  for (int side = 0; side < 4; ++side) {
    std::vector<Rect2> holes;
    if (side == front) holes.push_back({os0, os1, oy0, oy1});
    emitExteriorWall(cb, f, side, L, D, t, wallBot, top, wallTop, holes, wm);
  }
  f.box(cb, t, L - t, t, D - t, wallBot, base, slabMat());
  const Aabb thin = f.box(cb, m - 0.5 * tw, m + 0.5 * tw, t, D - t, base, yc, im);
  // Roof slab with a skylight over the lit room, beside the partition.
  const Rect2 sky{m - 0.5 * tw - 2.0, m - 0.5 * tw - 0.3, 0.5 * D - 1.0, 0.5 * D + 1.0};
  for (const Rect2& r : subtractHoles({t, L - t, t, D - t}, {sky}))
    f.box(cb, r.s0, r.s1, r.t0, r.t1, yc, top, roofMat());

  const int index = int(lay.buildings.size());
  Building bld;
  bld.footprint = f.aabb(0, L, 0, D, wallBot, wallTop);
  bld.bounds = bld.footprint;
  bld.storeys = 1;
  bld.storeyHeightM = float(h);
  bld.groundFloorY = float(base);
  bld.wallThicknessM = float(t);
  bld.roof = RoofKind::kFlatParapet;
  bld.firstRoom = int(lay.rooms.size());
  bld.roomCount = 2;
  bld.isLeakTest = true;
  Room lit;
  lit.air = f.aabb(t, m - 0.5 * tw, t, D - t, base, yc);
  lit.building = index;
  lit.openings = 2;  // facade opening + skylight
  Room sealed;
  sealed.air = f.aabb(m + 0.5 * tw, L - t, t, D - t, base, yc);
  sealed.building = index;
  sealed.sealed = true;
  LeakTestSite site;
  site.building = index;
  site.litRoom = int(lay.rooms.size());
  site.sealedRoom = site.litRoom + 1;
  site.thinWall = thin;
  site.thinWallThicknessM = float(tw);
  const double face = front == 0 ? 0.0 : D;
  site.opening = f.aabb(os0, os1, face, face, oy0, oy1);
  site.openingNormal = glm::vec3(front == 0 ? -f.dirV() : f.dirV());
  site.skylight = f.aabb(sky.s0, sky.s1, sky.t0, sky.t1, top, top);
  lay.rooms.push_back(lit);
  lay.rooms.push_back(sealed);
  lay.buildings.push_back(bld);
  lay.leakTests.push_back(site);
  return index;
}

// ---------------------------------------------------------------------------------------------------
// Block layouts. A lot is the block minus roads and sidewalks; everything stays inside it.

// Frame and (L, D) for a building strip of depth `depth` along lot side `side` (0: -Z, 1: +Z, 2: -X,
// 3: +X), starting `offset` along the side, `length` long. The facade towards the side is `front`.
struct StripPlacement {
  Frame f;
  int front = 0;
};
StripPlacement stripAlong(const Rect& lot, int side, double offset, double depth) {
  StripPlacement sp;
  switch (side) {
    case 0:
      sp.f = {lot.x0 + offset, lot.z0, true};
      sp.front = 0;
      break;
    case 1:
      sp.f = {lot.x0 + offset, lot.z1 - depth, true};
      sp.front = 1;
      break;
    case 2:
      sp.f = {lot.x0, lot.z0 + offset, false};
      sp.front = 0;
      break;
    default:
      sp.f = {lot.x1 - depth, lot.z0 + offset, false};
      sp.front = 1;
      break;
  }
  return sp;
}
double sideLength(const Rect& lot, int side) {
  return side < 2 ? lot.w() : lot.d();
}
Rect restOfLot(const Rect& lot, int side, double depth) {
  Rect r = lot;
  switch (side) {
    case 0:
      r.z0 += depth;
      break;
    case 1:
      r.z1 -= depth;
      break;
    case 2:
      r.x0 += depth;
      break;
    default:
      r.x1 -= depth;
      break;
  }
  return r;
}

BuildingPlan basePlan(Rng& rng, Frame f, double L, double D, int storeys) {
  BuildingPlan bp;
  bp.f = f;
  bp.L = L;
  bp.D = D;
  bp.storeys = storeys;
  bp.storeyH = rng.range(3.0, 3.4);
  bp.win.bay = rng.range(3.0, 4.0);
  bp.win.width = rng.range(1.2, 2.0);
  bp.win.sill = rng.range(0.7, 1.0);
  bp.win.head = std::min(bp.storeyH - bp.slabT - 0.25, rng.range(2.1, 2.5));
  bp.corridor = D >= 10.0;
  const glm::vec3 c = neutralFacade(rng);
  bp.facade = {c, c, c, c};
  if (rng.chance(0.4)) {
    bp.roof = RoofKind::kFlatOverhang;
    bp.overhang = rng.range(0.5, 1.0);
  } else {
    bp.parapet = rng.range(0.6, 1.0);
  }
  return bp;
}

// Orients a footprint rect (world) into a frame with u along the longer axis.
BuildingPlan planForRect(Rng& rng, const Rect& r, int storeys) {
  const bool ux = r.w() >= r.d();
  Frame f{r.x0, r.z0, ux};
  return basePlan(rng, f, ux ? r.w() : r.d(), ux ? r.d() : r.w(), storeys);
}

void layoutTowers(CellBuilder& cb, Rng rng, const Rect& lot, bool forceColour) {
  if (lot.w() < 8.0 || lot.d() < 8.0) return;
  const double g = rng.range(3.0, 6.0);
  const int nx = lot.w() >= 30.0 && rng.chance(0.75) ? 2 : 1;
  const int nz = lot.d() >= 30.0 && rng.chance(0.75) ? 2 : 1;
  const double fx = nx == 2 ? rng.range(0.4, 0.6) : 1.0, fz = nz == 2 ? rng.range(0.4, 0.6) : 1.0;
  const double xs = lot.x0 + fx * (lot.w() - (nx - 1) * g), zs = lot.z0 + fz * (lot.d() - (nz - 1) * g);
  int built = 0;
  for (int j = 0; j < nz; ++j)
    for (int i = 0; i < nx; ++i) {
      Rng br = rng.child(j * 2 + i);
      Rect p{i == 0 ? lot.x0 : xs + g, j == 0 ? lot.z0 : zs + g, i == 0 && nx == 2 ? xs : lot.x1,
             j == 0 && nz == 2 ? zs : lot.z1};
      // Setbacks inside the parcel.
      p = {p.x0 + br.range(0.0, 1.5), p.z0 + br.range(0.0, 1.5), p.x1 - br.range(0.0, 1.5),
           p.z1 - br.range(0.0, 1.5)};
      if (p.w() < 8.0 || p.d() < 8.0) continue;
      if (built > 0 && br.chance(0.08)) continue;  // an empty parcel now and then (a small square)
      const int storeys = std::min(8, 2 + br.irange(0, 3) + br.irange(0, 3));
      BuildingPlan bp = planForRect(br, p, storeys);
      bp.entrance = br.irange(0, 3);
      if ((forceColour && built == 0) || br.chance(0.15)) {
        const glm::vec3 c = saturatedFacade(br);
        bp.facade = {c, c, c, c};
      }
      emitBuilding(cb, bp, br);
      ++built;
    }
}

void layoutCourtyard(CellBuilder& cb, Rng rng, const Rect& lotIn) {
  // Centre a ring of at most 56 m inside the lot.
  Rect lot = lotIn;
  const double mw = std::max(0.0, lot.w() - 56.0), md = std::max(0.0, lot.d() - 56.0);
  lot = {lot.x0 + 0.5 * mw, lot.z0 + 0.5 * md, lot.x1 - 0.5 * mw, lot.z1 - 0.5 * md};
  const double d = rng.range(8.0, 10.5);
  if (lot.w() < 2 * d + 12.0 || lot.d() < 2 * d + 12.0) {
    layoutTowers(cb, rng, lotIn, true);
    return;
  }
  const int storeys = rng.irange(2, 5);
  const double storeyH = rng.range(3.0, 3.3);
  const glm::vec3 street = neutralFacade(rng);
  const glm::vec3 white{0.8f, 0.78f, 0.74f};
  const double W = lot.w(), H = lot.d();
  Courtyard court;
  // S and N wings run the full width; W and E wings fit between them.
  struct Wing {
    Frame f;
    double L;
    int yardSide, streetSide;
    glm::vec3 yard;
  };
  const Wing wings[4] = {
      {{lot.x0, lot.z0, true}, W, 1, 0, kRed},
      {{lot.x0, lot.z1 - d, true}, W, 0, 1, kGreen},
      {{lot.x0, lot.z0 + d, false}, H - 2 * d, 1, 0, kBlue},
      {{lot.x1 - d, lot.z0 + d, false}, H - 2 * d, 0, 1, white},
  };
  double minTop = 1e30;
  for (int w = 0; w < 4; ++w) {
    Rng wr = rng.child(w);
    BuildingPlan bp = basePlan(wr, wings[w].f, wings[w].L, d, storeys);
    bp.storeyH = storeyH;
    bp.win.head = std::min(bp.storeyH - bp.slabT - 0.25, bp.win.head);
    bp.roof = RoofKind::kFlatParapet;  // overhangs would cut into the neighbouring wings
    bp.parapet = 0.8;
    bp.courtyardWing = true;
    bp.entrance = wings[w].streetSide;
    bp.facade = {street, street, street, street};
    bp.facade[size_t(wings[w].yardSide)] = wings[w].yard;
    if (w < 2) {
      // The W/E wings' end walls cover the first and last d metres of the yard facade.
      bp.blocked[size_t(wings[w].yardSide)] = {{-1.0, d + 0.1}, {W - d - 0.1, W + 1.0}};
    } else {
      bp.blocked[2] = {{-1e9, 1e9}};
      bp.blocked[3] = {{-1e9, 1e9}};
    }
    const int wing = emitBuilding(cb, bp, wr);
    if (wing >= 0) court.wings.push_back(wing);
    minTop = std::min(minTop, bp.base + storeys * storeyH);
  }
  court.yard = makeAabb({lot.x0 + d, 0.0, lot.z0 + d}, {lot.x1 - d, minTop, lot.z1 - d});
  if (court.wings.size() == 4) cb.layout().courtyards.push_back(court);  // a cleared wing opens the ring
}

void layoutArcade(CellBuilder& cb, Rng rng, const Rect& lot, int side) {
  const double ad = rng.range(2.6, 3.4), D = rng.range(11.0, 13.0);
  const double depth = ad + 0.25 + D;
  const double len = sideLength(lot, side) - 2.0;
  if (len < 12.0 || (side < 2 ? lot.d() : lot.w()) < depth + 1.0) {
    layoutTowers(cb, rng, lot, false);
    return;
  }
  StripPlacement sp = stripAlong(lot, side, 1.0, depth);
  // The building starts behind the arcade: shift the frame origin along v.
  Frame f = sp.f;
  const double shift = sp.front == 0 ? ad + 0.25 : 0.0;
  if (f.uAlongX)
    f.oz += shift;
  else
    f.ox += shift;
  Rng br = rng.child(1);
  BuildingPlan bp = basePlan(br, f, len, D, br.irange(3, 6));
  bp.arcadeSide = sp.front;
  bp.arcadeDepth = ad;
  bp.entrance = sp.front;
  emitBuilding(cb, bp, br);
  const Rect rest = restOfLot(lot, side, depth + rng.range(4.0, 7.0));
  layoutTowers(cb, rng.child(2), rest, false);
}

void layoutLeakTest(CellBuilder& cb, Rng rng, const Rect& lot, int side) {
  const double L = rng.range(12.0, 14.0), D = rng.range(6.5, 7.5);
  if (sideLength(lot, side) < L + 2.0 || (side < 2 ? lot.d() : lot.w()) < D + 1.0) {
    layoutTowers(cb, rng, lot, false);
    return;
  }
  const double offset = rng.range(1.0, sideLength(lot, side) - L - 1.0);
  StripPlacement sp = stripAlong(lot, side, offset, D);
  emitLeakHouse(cb, sp.f, L, D, sp.front, neutralFacade(rng), rng.child(1));
  const Rect rest = restOfLot(lot, side, D + rng.range(5.0, 8.0));
  layoutTowers(cb, rng.child(2), rest, false);
}

void layoutHouses(CellBuilder& cb, Rng rng, const Rect& lot) {
  const int nx = lot.w() >= 26.0 ? 2 : 1, nz = lot.d() >= 26.0 ? 2 : 1;
  const double pw = lot.w() / nx, pd = lot.d() / nz;
  for (int j = 0; j < nz; ++j)
    for (int i = 0; i < nx; ++i) {
      Rng hr = rng.child(j * 2 + i);
      if (hr.chance(0.12)) continue;  // a garden plot
      const double w = std::min(pw - 3.0, hr.range(8.0, 12.0)), d = std::min(pd - 3.0, hr.range(7.0, 10.0));
      if (w < 6.0 || d < 6.0) continue;
      const double x0 = lot.x0 + i * pw + hr.range(1.5, pw - w - 1.5);
      const double z0 = lot.z0 + j * pd + hr.range(1.5, pd - d - 1.5);
      BuildingPlan bp = planForRect(hr, {x0, z0, x0 + w, z0 + d}, hr.irange(1, 2));
      bp.corridor = false;
      bp.storeyH = hr.range(2.8, 3.1);
      bp.win.head = std::min(bp.storeyH - bp.slabT - 0.25, bp.win.head);
      bp.win.glazedP = 0.7;
      bp.win.litP = 0.15;
      bp.entrance = hr.irange(0, 3);
      if (hr.chance(0.75)) {
        bp.roof = RoofKind::kFlatOverhang;
        bp.overhang = hr.range(0.6, 1.2);
      }
      static const glm::vec3 kPastel[] = {
          {0.8f, 0.72f, 0.55f}, {0.65f, 0.75f, 0.7f}, {0.82f, 0.8f, 0.76f}, {0.75f, 0.6f, 0.55f}};
      glm::vec3 c = hr.chance(0.15) ? saturatedFacade(hr) : kPastel[hr.irange(0, 3)];
      bp.facade = {c, c, c, c};
      emitBuilding(cb, bp, hr);
    }
}

void addLamp(CellBuilder& cb, double x, double z, double ground) {
  if (cb.cleared({x - 0.35, z - 0.35, x + 0.35, z + 0.35})) return;
  const double top = ground + 5.4;
  cb.box({x - 0.08, ground - 0.1, z - 0.08}, {x + 0.08, top - 0.15, z + 0.08},
         propMat("lamp_pole", {0.2f, 0.2f, 0.22f}));
  const Aabb head = cb.box({x - 0.3, top - 0.15, z - 0.3}, {x + 0.3, top, z + 0.3}, lampHeadMat());
  cb.box({x - 0.35, top, z - 0.35}, {x + 0.35, top + 0.1, z + 0.35},
         propMat("lamp_cap", {0.15f, 0.15f, 0.16f}));
  Emitter e;
  e.kind = EmitterKind::kStreetLamp;
  e.box = head;
  e.normal = {0.0f, -1.0f, 0.0f};
  e.radiance = kLampRadiance;
  const glm::vec3 s = head.size();
  e.areaM2 = 2.0f * (s.x * s.y + s.y * s.z + s.x * s.z);
  cb.layout().emitters.push_back(e);
}

void layoutPark(CellBuilder& cb, Rng rng, const Rect& lot) {
  std::vector<glm::dvec2> trees;
  const int want = rng.irange(6, 12);
  for (int attempt = 0; attempt < 60 && int(trees.size()) < want; ++attempt) {
    const glm::dvec2 p{rng.range(lot.x0 + 2.5, lot.x1 - 2.5), rng.range(lot.z0 + 2.5, lot.z1 - 2.5)};
    bool ok = true;
    for (const glm::dvec2& q : trees) ok = ok && glm::length(p - q) > 6.0;
    if (!ok) continue;
    trees.push_back(p);
    const double r = rng.range(1.4, 2.2), th = rng.range(2.0, 3.0), ch = rng.range(2.5, 4.0);
    if (cb.cleared({p.x - r, p.y - r, p.x + r, p.y + r})) continue;
    cb.box({p.x - 0.2, -0.1, p.y - 0.2}, {p.x + 0.2, th, p.y + 0.2},
           propMat("tree_trunk", {0.25f, 0.16f, 0.1f}));
    cb.box({p.x - r, th, p.y - r}, {p.x + r, th + ch, p.y + r}, propMat("tree_canopy", {0.1f, 0.3f, 0.08f}));
  }
  // Benches along the middle path, and a lamp at the centre.
  const double cx = 0.5 * (lot.x0 + lot.x1), cz = 0.5 * (lot.z0 + lot.z1);
  for (int b = -1; b <= 1; b += 2) {
    const double bx = cx + b * 4.0;
    bool clear = true;
    for (const glm::dvec2& q : trees) clear = clear && glm::length(q - glm::dvec2(bx, cz)) > 3.5;
    if (clear && !cb.cleared({bx - 0.9, cz - 0.25, bx + 0.9, cz + 0.25}))
      cb.box({bx - 0.9, -0.05, cz - 0.25}, {bx + 0.9, 0.45, cz + 0.25}, propMat("bench", {0.4f, 0.3f, 0.2f}));
  }
  bool clear = true;
  for (const glm::dvec2& q : trees) clear = clear && glm::length(q - glm::dvec2(cx, cz)) > 3.0;
  if (clear) addLamp(cb, cx, cz, 0.0);
}

// Street lamps along the inner side of every road edge of the cell; a lamp every ~22 m in urban cells,
// every ~40 m along main roads through fields.
void placeLamps(CellBuilder& cb, const WorldView& w, int64_t cx, int64_t cz) {
  const bool urban = isUrban(w.kindAt(cx, cz));
  const double x0 = w.cellOrigin(cx), x1 = w.cellOrigin(cx + 1), z0 = w.cellOrigin(cz),
               z1 = w.cellOrigin(cz + 1);
  const double pitch = urban ? 22.0 : 40.0;
  std::vector<Rect> roads;
  w.roadRects(cx, cz, roads);
  auto clearOfRoads = [&](double x, double z) {
    for (const Rect& r : roads)
      if (r.distance(x, z) < 0.6) return false;
    return true;
  };
  for (int edge = 0; edge < 4; ++edge) {
    const bool vertical = edge < 2;
    const int64_t e = vertical ? cx + edge : cz + (edge - 2);
    const int64_t c = vertical ? cz : cx;
    if (!w.segmentHasRoad(vertical, e, c)) continue;
    if (!urban && !w.mainLine(e)) continue;
    const double off = w.lineHalfWidth(e) + 0.8;
    const double across = (edge % 2 == 0) ? w.cellOrigin(e) + off : w.cellOrigin(e) - off;
    // Keep clear of the crossing roads at both ends of the edge.
    const int64_t lo = vertical ? cz : cx;
    const double a0 = (vertical ? z0 : x0) +
                      (w.segmentHasRoad(!vertical, lo, vertical ? cx : cz) ? w.lineHalfWidth(lo) : 0.0) + 3.0;
    const double a1 =
        (vertical ? z1 : x1) -
        (w.segmentHasRoad(!vertical, lo + 1, vertical ? cx : cz) ? w.lineHalfWidth(lo + 1) : 0.0) - 3.0;
    if (a1 <= a0) continue;
    const int count = std::max(1, int(std::floor((a1 - a0) / pitch)));
    for (int i = 0; i < count; ++i) {
      const double along = a0 + (double(i) + 0.5) * (a1 - a0) / double(count);
      const double lx = vertical ? across : along, lz = vertical ? along : across;
      if (clearOfRoads(lx, lz)) addLamp(cb, lx, lz, 0.0);
    }
  }
}

// Open field: at most four low props (hay bales, rocks) on the hills, away from roads.
void layoutField(CellBuilder& cb, const WorldView& w, Rng rng, int64_t cx, int64_t cz) {
  const double x0 = w.cellOrigin(cx), z0 = w.cellOrigin(cz);
  std::vector<Rect> roads;
  w.roadRects(cx, cz, roads);
  const int count = rng.irange(0, 4);
  std::vector<Rect> placed;
  for (int i = 0; i < count; ++i) {
    const bool hay = rng.chance(0.5);
    const double sx = hay ? 1.4 : rng.range(0.6, 1.4), sz = hay ? 1.2 : rng.range(0.6, 1.4);
    const double hgt = hay ? 1.2 : rng.range(0.4, 0.9);
    const double px = x0 + rng.range(sx + 1.0, w.cellM - sx - 1.0),
                 pz = z0 + rng.range(sz + 1.0, w.cellM - sz - 1.0);
    bool clear = true;
    for (const Rect& r : roads) clear = clear && r.distance(px, pz) > 4.0 + std::max(sx, sz);
    for (const Rect& r : placed) clear = clear && r.distance(px, pz) > 1.0 + std::max(sx, sz);
    if (!clear) continue;
    placed.push_back({px - 0.5 * sx, pz - 0.5 * sz, px + 0.5 * sx, pz + 0.5 * sz});
    double lo = 1e30, hi = -1e30;
    for (double ax : {-0.5, 0.0, 0.5})
      for (double az : {-0.5, 0.0, 0.5}) {
        const double y = w.terrainHeight(px + ax * sx, pz + az * sz);
        lo = std::min(lo, y);
        hi = std::max(hi, y);
      }
    if (cb.cleared({px - 0.5 * sx, pz - 0.5 * sz, px + 0.5 * sx, pz + 0.5 * sz})) continue;
    cb.box({px - 0.5 * sx, lo - 0.3, pz - 0.5 * sz}, {px + 0.5 * sx, hi + hgt, pz + 0.5 * sz},
           hay ? propMat("hay_bale", {0.6f, 0.5f, 0.2f}) : propMat("rock", {0.4f, 0.4f, 0.38f}));
  }
}

// ---------------------------------------------------------------------------------------------------
// Terrain and roads.

void emitTerrain(CellBuilder& cb, const WorldView& w, int64_t cx, int64_t cz, float& minY, float& maxY) {
  const int n = w.quads;
  const int64_t i0 = cx * n, j0 = cz * n;
  std::vector<float> hts(size_t(n + 1) * size_t(n + 1));
  minY = 1e30f;
  maxY = -1e30f;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const float y = w.latticeHeight(i0 + i, j0 + j);
      hts[size_t(j) * size_t(n + 1) + size_t(i)] = y;
      minY = std::min(minY, y);
      maxY = std::max(maxY, y);
    }
  TriangleMesh* mesh = cb.mesh();
  if (!mesh) return;
  const CellKind kind = w.kindAt(cx, cz);
  const MatSpec m =
      kind == CellKind::kField  ? mat("terrain_grass", {0.16f, 0.26f, 0.08f}, SurfaceCategory::kTerrain)
      : kind == CellKind::kPark ? mat("terrain_lawn", {0.14f, 0.3f, 0.07f}, SurfaceCategory::kTerrain)
                                : mat("terrain_paving", {0.32f, 0.31f, 0.3f}, SurfaceCategory::kTerrain);
  const uint32_t mi = cb.material(m);
  const uint32_t base = uint32_t(mesh->positions.size());
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i)
      mesh->positions.emplace_back(float(w.latticeCoord(i0 + i)), hts[size_t(j) * size_t(n + 1) + size_t(i)],
                                   float(w.latticeCoord(j0 + j)));
  if (!mesh->uvs.empty()) mesh->uvs.resize(mesh->positions.size(), glm::vec2(0.0f));
  auto at = [&](int i, int j) { return base + uint32_t(j) * uint32_t(n + 1) + uint32_t(i); };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      // Split along (i, j+1)-(i+1, j), as terrainHeight() assumes; counter-clockwise seen from +Y.
      mesh->indices.insert(mesh->indices.end(), {at(i, j), at(i, j + 1), at(i + 1, j)});
      mesh->indices.insert(mesh->indices.end(), {at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)});
      mesh->triangleMaterial.insert(mesh->triangleMaterial.end(), {mi, mi});
    }
}

// Road strips: the union of the cell's road rectangles cut on a grid of all rectangle edges (also the
// edge neighbours', so a skirt faces uniform ground), top faces merged along X, and 8 cm skirts wherever
// a strip borders non-road ground.
void emitRoads(CellBuilder& cb, const WorldView& w, int64_t cx, int64_t cz) {
  std::vector<Rect> mine, other;
  w.roadRects(cx, cz, mine);
  if (mine.empty() || !cb.hasMesh()) return;
  const double x0 = w.cellOrigin(cx), x1 = w.cellOrigin(cx + 1), z0 = w.cellOrigin(cz),
               z1 = w.cellOrigin(cz + 1);
  std::vector<double> xs{x0, x1}, zs{z0, z1};
  auto addCuts = [&](const std::vector<Rect>& rs) {
    for (const Rect& r : rs) {
      for (double x : {r.x0, r.x1})
        if (x > x0 && x < x1) xs.push_back(x);
      for (double z : {r.z0, r.z1})
        if (z > z0 && z < z1) zs.push_back(z);
    }
  };
  addCuts(mine);
  for (const auto& [dx, dz] : {std::pair{-1, 0}, std::pair{1, 0}, std::pair{0, -1}, std::pair{0, 1}}) {
    w.roadRects(cx + dx, cz + dz, other);
    addCuts(other);
  }
  for (auto* v : {&xs, &zs}) {
    std::sort(v->begin(), v->end());
    v->erase(std::unique(v->begin(), v->end()), v->end());
  }
  auto road = [&](size_t i, size_t j) {
    const double mx = 0.5 * (xs[i] + xs[i + 1]), mz = 0.5 * (zs[j] + zs[j + 1]);
    for (const Rect& r : mine)
      if (r.containsHalfOpen(mx, mz)) return true;
    return false;
  };
  const MatSpec rm = mat("road_asphalt", {0.08f, 0.08f, 0.085f}, SurfaceCategory::kRoad);
  const double y = kRoadRaiseM;
  for (size_t j = 0; j + 1 < zs.size(); ++j) {
    size_t i = 0;
    while (i + 1 < xs.size()) {
      if (!road(i, j)) {
        ++i;
        continue;
      }
      size_t k = i;
      while (k + 1 < xs.size() && road(k, j)) ++k;
      cb.quad({xs[i], y, zs[j]}, {xs[i], y, zs[j + 1]}, {xs[k], y, zs[j + 1]}, {xs[k], y, zs[j]}, {0, 1, 0},
              rm);
      i = k;
    }
    for (size_t ii = 0; ii + 1 < xs.size(); ++ii) {
      if (!road(ii, j)) continue;
      const double ax = xs[ii], bx = xs[ii + 1], az = zs[j], bz = zs[j + 1];
      const double mx = 0.5 * (ax + bx), mz = 0.5 * (az + bz), eps = 0.01;
      if (!w.isRoad(ax - eps, mz))
        cb.quad({ax, 0, az}, {ax, y, az}, {ax, y, bz}, {ax, 0, bz}, {-1, 0, 0}, rm);
      if (!w.isRoad(bx + eps, mz)) cb.quad({bx, 0, az}, {bx, y, az}, {bx, y, bz}, {bx, 0, bz}, {1, 0, 0}, rm);
      if (!w.isRoad(mx, az - eps))
        cb.quad({ax, 0, az}, {ax, y, az}, {bx, y, az}, {bx, 0, az}, {0, 0, -1}, rm);
      if (!w.isRoad(mx, bz + eps)) cb.quad({ax, 0, bz}, {ax, y, bz}, {bx, y, bz}, {bx, 0, bz}, {0, 0, 1}, rm);
    }
  }
}

// Lot of block (bi, bj) of an urban cell: the block minus the roads around it and the sidewalk. Also
// reports which lot sides face a road.
Rect blockLot(const WorldView& w, int64_t cx, int64_t cz, int bi, int bj, std::array<bool, 4>& roadSide) {
  const int nb = w.blocksPerCell();
  const double pitch = w.cellM / double(nb);
  const double x0 = w.cellOrigin(cx) + bi * pitch, z0 = w.cellOrigin(cz) + bj * pitch;
  const double x1 = bi + 1 == nb ? w.cellOrigin(cx + 1) : x0 + pitch;
  const double z1 = bj + 1 == nb ? w.cellOrigin(cz + 1) : z0 + pitch;
  // Inset per side: inner streets, or the cell edge's road if its segment has one.
  auto inset = [&](bool vertical, bool low, int b, int64_t cellIdx, int64_t other) {
    if (low ? b > 0 : b + 1 < nb) return std::pair{true, kStreetHalfWidth};
    const int64_t e = low ? cellIdx : cellIdx + 1;
    if (w.segmentHasRoad(vertical, e, other)) return std::pair{true, w.lineHalfWidth(e)};
    return std::pair{false, 0.0};
  };
  const auto [r0, i0] = inset(false, true, bj, cz, cx);   // -Z side: horizontal line
  const auto [r1, i1] = inset(false, false, bj, cz, cx);  // +Z
  const auto [r2, i2] = inset(true, true, bi, cx, cz);    // -X: vertical line
  const auto [r3, i3] = inset(true, false, bi, cx, cz);   // +X
  roadSide = {r0, r1, r2, r3};
  return {x0 + i2 + kSidewalk, z0 + i0 + kSidewalk, x1 - i3 - kSidewalk, z1 - i1 - kSidewalk};
}

int pickRoadSide(Rng& rng, const std::array<bool, 4>& roadSide, int preferred) {
  if (preferred >= 0 && roadSide[size_t(preferred)]) return preferred;
  std::vector<int> sides;
  for (int s = 0; s < 4; ++s)
    if (roadSide[size_t(s)]) sides.push_back(s);
  if (sides.empty()) return rng.irange(0, 3);
  return sides[rng.next() % sides.size()];
}

WorldView viewOf(const SyntheticWorld& world) {
  return WorldView{world.params().seed, world.params().cellM, world.cellsX(), world.terrainQuadsPerCell(),
                   world.mainRoadSpacingCells()};
}

// ---------------------------------------------------------------------------------------------------
// World edits (world_edits.h).

Rect editRect(const WorldEdit& e) {
  return {e.min.x, e.min.z, e.max.x, e.max.z};
}
bool overlaps(const Rect& a, const Rect& b) {
  return a.x0 < b.x1 && b.x0 < a.x1 && a.z0 < b.z1 && b.z0 < a.z1;
}

// What the edits do to one cell: the regions that clear generated content, and the additions the cell
// owns (clipped to it) that no later clear-region/add-building removes.
struct CellEditPlan {
  std::vector<Rect> clears;
  struct Add {
    size_t index;
    Rect xz;
  };
  std::vector<Add> adds;
};
CellEditPlan cellEditPlan(const std::vector<WorldEdit>& edits, const Rect& cell) {
  CellEditPlan plan;
  for (size_t i = 0; i < edits.size(); ++i) {
    const WorldEdit& e = edits[i];
    const Rect r = editRect(e);
    if (!overlaps(r, cell)) continue;
    if (e.kind != WorldEditKind::kAddBox) plan.clears.push_back(r);
    if (e.kind == WorldEditKind::kClearRegion) continue;
    const Rect piece{std::max(r.x0, cell.x0), std::max(r.z0, cell.z0), std::min(r.x1, cell.x1),
                     std::min(r.z1, cell.z1)};
    bool removed = false;
    for (size_t j = i + 1; j < edits.size() && !removed; ++j)
      removed = edits[j].kind != WorldEditKind::kAddBox && overlaps(editRect(edits[j]), piece);
    if (!removed) plan.adds.push_back({i, piece});
  }
  return plan;
}

// Lowest and highest terrain-mesh height over a rectangle, exactly: a piecewise-linear surface takes its
// extremes over a convex region at vertices of the overlay (lattice vertices inside, the rectangle's
// corners, its crossings with lattice lines and with the triangles' diagonals).
void terrainRange(const WorldView& w, const Rect& r, double& lo, double& hi) {
  lo = 1e30;
  hi = -1e30;
  auto at = [&](double x, double z) {
    const double y = w.terrainHeight(x, z);
    lo = std::min(lo, y);
    hi = std::max(hi, y);
  };
  const int64_t i0 = w.latticeIndexBelow(r.x0), i1 = w.latticeIndexBelow(r.x1);
  const int64_t j0 = w.latticeIndexBelow(r.z0), j1 = w.latticeIndexBelow(r.z1);
  std::vector<double> xs{r.x0, r.x1}, zs{r.z0, r.z1};
  for (int64_t i = i0; i <= i1 + 1; ++i)
    if (const double x = w.latticeCoord(i); x > r.x0 && x < r.x1) xs.push_back(x);
  for (int64_t j = j0; j <= j1 + 1; ++j)
    if (const double z = w.latticeCoord(j); z > r.z0 && z < r.z1) zs.push_back(z);
  for (double x : xs)
    for (double z : zs) at(x, z);
  for (double ze : {r.z0, r.z1}) {  // diagonals fx + fz = 1 crossing the edges z = ze
    const int64_t j = w.latticeIndexBelow(ze);
    const double fz = (ze - w.latticeCoord(j)) / (w.latticeCoord(j + 1) - w.latticeCoord(j));
    for (int64_t i = i0; i <= i1; ++i) {
      const double xa = w.latticeCoord(i), x = xa + (1.0 - fz) * (w.latticeCoord(i + 1) - xa);
      if (x >= r.x0 && x <= r.x1) at(x, ze);
    }
  }
  for (double xe : {r.x0, r.x1}) {
    const int64_t i = w.latticeIndexBelow(xe);
    const double fx = (xe - w.latticeCoord(i)) / (w.latticeCoord(i + 1) - w.latticeCoord(i));
    for (int64_t j = j0; j <= j1; ++j) {
      const double za = w.latticeCoord(j), z = za + (1.0 - fx) * (w.latticeCoord(j + 1) - za);
      if (z >= r.z0 && z <= r.z1) at(xe, z);
    }
  }
}

void emitEditBuilding(CellBuilder& cb, const WorldView& w, const WorldEdit& e, size_t index) {
  Rng rng(hashKey(w.seed, kPurposeEdit, int64_t(index)));
  const Rect r = editRect(e);
  double lo = 0.0, hi = 0.0;
  terrainRange(w, r, lo, hi);
  BuildingPlan bp = planForRect(rng, r, e.storeys);
  bp.roof = RoofKind::kFlatParapet;  // no overhang: the building stays on its footprint, inside the cell
  bp.overhang = 0.0;
  bp.parapet = rng.range(0.6, 1.0);
  bp.entrance = rng.irange(0, 3);
  bp.base = hi + 0.15;
  bp.edit = true;
  // Sloped ground: a plinth under the walls down into the terrain, so no gap opens under the building.
  if (lo < hi)
    cb.box({r.x0, lo - 0.3, r.z0}, {r.x1, bp.base - bp.slabT, r.z1},
           mat("edit_plinth", {0.45f, 0.44f, 0.42f}, SurfaceCategory::kWall));
  emitBuilding(cb, bp, rng);
}

void applyEditAdds(CellBuilder& cb, const WorldView& w, const std::vector<WorldEdit>& edits,
                   const CellEditPlan& plan) {
  for (const CellEditPlan::Add& a : plan.adds) {
    const WorldEdit& e = edits[a.index];
    if (e.kind == WorldEditKind::kAddBuilding) {
      emitEditBuilding(cb, w, e, a.index);
    } else {
      cb.box({a.xz.x0, e.min.y, a.xz.z0}, {a.xz.x1, e.max.y, a.xz.z1},
             mat(fmt::format("edit_box_{}", categoryName(e.category)), {0.5f, 0.5f, 0.5f}, e.category));
    }
  }
}

void buildCell(const WorldView& w, const std::vector<WorldEdit>& edits, CellCoord c, TriangleMesh* mesh,
               CellLayout& layout) {
  layout = CellLayout{};
  layout.cell = c;
  layout.kind = w.kindAt(c.x, c.z);
  layout.block = w.blockAt(c.x, c.z, 0, 0);
  CellBuilder cb(mesh, layout);
  const CellEditPlan editPlan = cellEditPlan(
      edits, {w.cellOrigin(c.x), w.cellOrigin(c.z), w.cellOrigin(c.x + 1), w.cellOrigin(c.z + 1)});
  cb.setClears(editPlan.clears);
  float minY = 0.0f, maxTerrain = 0.0f;
  emitTerrain(cb, w, c.x, c.z, minY, maxTerrain);
  emitRoads(cb, w, c.x, c.z);
  const Rng cellRng(hashKey(w.seed, kPurposeBlock, c.x, c.z));
  if (layout.kind == CellKind::kField) {
    layoutField(cb, w, Rng(hashKey(w.seed, kPurposeField, c.x, c.z)), c.x, c.z);
  } else {
    const int nb = w.blocksPerCell();
    for (int bj = 0; bj < nb; ++bj)
      for (int bi = 0; bi < nb; ++bi) {
        std::array<bool, 4> roadSide{};
        const Rect lot = blockLot(w, c.x, c.z, bi, bj, roadSide);
        Rng br = cellRng.child(bj * nb + bi);
        const bool show = w.showcase(c.x, c.z);
        switch (w.blockAt(c.x, c.z, bi, bj)) {
          case BlockType::kTowers:
            layoutTowers(cb, br, lot, show);
            break;
          case BlockType::kCourtyard:
            layoutCourtyard(cb, br, lot);
            break;
          case BlockType::kArcade:
            layoutArcade(cb, br, lot, pickRoadSide(br, roadSide, show ? 2 : -1));
            break;
          case BlockType::kLeakTest:
            layoutLeakTest(cb, br, lot, pickRoadSide(br, roadSide, show ? 0 : -1));
            break;
          case BlockType::kHouses:
            layoutHouses(cb, br, lot);
            break;
          case BlockType::kPark:
            layoutPark(cb, br, lot);
            break;
          case BlockType::kNone:
            break;
        }
      }
  }
  placeLamps(cb, w, c.x, c.z);
  applyEditAdds(cb, w, edits, editPlan);
  const glm::vec3 lo(float(w.cellOrigin(c.x)), minY, float(w.cellOrigin(c.z)));
  const glm::vec3 hi(float(w.cellOrigin(c.x + 1)), std::max({cb.maxY(), maxTerrain, kRoadRaiseM}),
                     float(w.cellOrigin(c.z + 1)));
  layout.bounds = Aabb{lo, hi};
}

}  // namespace

// ---------------------------------------------------------------------------------------------------

std::string_view cellKindName(CellKind k) {
  switch (k) {
    case CellKind::kField:
      return "field";
    case CellKind::kSuburb:
      return "suburb";
    case CellKind::kCity:
      return "city";
    case CellKind::kPark:
      return "park";
  }
  return "unknown";
}

std::string_view blockTypeName(BlockType t) {
  switch (t) {
    case BlockType::kTowers:
      return "towers";
    case BlockType::kCourtyard:
      return "courtyard";
    case BlockType::kArcade:
      return "arcade";
    case BlockType::kLeakTest:
      return "leak_test";
    case BlockType::kHouses:
      return "houses";
    case BlockType::kPark:
      return "park";
    case BlockType::kNone:
      return "none";
  }
  return "unknown";
}

void WorldParams::validate() const {
  if (!std::isfinite(cellM) || cellM < 16.0 || cellM > 512.0)
    fail("synthetic world: cell size {} m is outside [16, 512]", cellM);
  if (!std::isfinite(sizeM) || sizeM <= 0.0)
    fail("synthetic world: size {} m must be positive and finite", sizeM);
  const double n = std::round(sizeM / cellM);
  if (n < 1.0 || std::abs(n * cellM - sizeM) > 1e-9 * sizeM)
    fail("synthetic world: size {} m is not a whole multiple of the cell size {} m", sizeM, cellM);
  if (n > 65536.0) fail("synthetic world: {} cells per axis is more than 65536", n);
  validateWorldEdits(edits, sizeM, cellM);
}

bool CellLayout::insideSolid(glm::vec3 p, float margin) const {
  for (const SolidBox& s : solids)
    if (p.x > s.box.min.x + margin && p.x < s.box.max.x - margin && p.y > s.box.min.y + margin &&
        p.y < s.box.max.y - margin && p.z > s.box.min.z + margin && p.z < s.box.max.z - margin)
      return true;
  return false;
}

SyntheticWorld::SyntheticWorld(const WorldParams& params) : params_(params) {
  params_.validate();
  cells_ = int(std::round(params_.sizeM / params_.cellM));
  terrainQuads_ = std::max(4, int(std::lround(params_.cellM / 4.0)));
  mainSpacing_ = std::max(2, int(std::lround(128.0 / params_.cellM)));
}

void SyntheticWorld::requireCell(CellCoord c) const {
  if (!contains(c))
    fail("synthetic world: cell ({}, {}) is outside the {}×{} cells of this world", c.x, c.z, cells_, cells_);
}

Aabb SyntheticWorld::cellBounds(CellCoord c) const {
  requireCell(c);
  return Aabb{
      glm::vec3(float(double(c.x) * params_.cellM), 0.0f, float(double(c.z) * params_.cellM)),
      glm::vec3(float(double(c.x + 1) * params_.cellM), 0.0f, float(double(c.z + 1) * params_.cellM))};
}

CellKind SyntheticWorld::cellKind(CellCoord c) const {
  requireCell(c);
  return viewOf(*this).kindAt(c.x, c.z);
}

BlockType SyntheticWorld::blockType(CellCoord c) const {
  requireCell(c);
  return viewOf(*this).blockAt(c.x, c.z, 0, 0);
}

float SyntheticWorld::terrainHeight(float x, float z) const {
  return viewOf(*this).terrainHeight(x, z);
}

bool SyntheticWorld::isRoad(float x, float z) const {
  return viewOf(*this).isRoad(x, z);
}

std::vector<CellCoord> SyntheticWorld::editCells(const WorldEdit& e) const {
  std::vector<CellCoord> out;
  const double m = params_.cellM, last = double(cells_ - 1);
  for (double v : {e.min.x, e.min.z, e.max.x, e.max.z})
    if (!std::isfinite(v)) return out;
  const int x0 = int(std::clamp(std::floor(e.min.x / m), 0.0, last)),
            z0 = int(std::clamp(std::floor(e.min.z / m), 0.0, last));
  const int x1 = int(std::clamp(std::ceil(e.max.x / m) - 1.0, -1.0, last)),
            z1 = int(std::clamp(std::ceil(e.max.z / m) - 1.0, -1.0, last));
  for (int z = z0; z <= z1; ++z)
    for (int x = x0; x <= x1; ++x)
      if (overlaps(editRect(e), {double(x) * m, double(z) * m, double(x + 1) * m, double(z + 1) * m}))
        out.push_back({x, z});
  return out;
}

TriangleMesh SyntheticWorld::generateCell(CellCoord c) const {
  return generate(c).mesh;
}

CellLayout SyntheticWorld::describeCell(CellCoord c) const {
  requireCell(c);
  CellLayout layout;
  buildCell(viewOf(*this), params_.edits, c, nullptr, layout);
  return layout;
}

GeneratedCell SyntheticWorld::generate(CellCoord c) const {
  requireCell(c);
  GeneratedCell out;
  buildCell(viewOf(*this), params_.edits, c, &out.mesh, out.layout);
  out.mesh.validate(fmt::format("synthetic cell ({}, {})", c.x, c.z));
  return out;
}

}  // namespace lfgi::worlds
