#include "worlds/synthetic_world.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <set>
#include <tuple>
#include <vector>

#include "core/error.h"

namespace lfgi::worlds {
namespace {

// Segment p -> q against triangle t (Möller–Trumbore in double, edges inclusive so a segment through a
// shared edge cannot slip between two triangles). Returns the hit parameter in [0, 1], or -1.
double segmentHit(const TriangleMesh& m, size_t t, glm::dvec3 p, glm::dvec3 q) {
  const glm::dvec3 d = q - p;
  const glm::dvec3 a(m.vertex(t, 0)), b(m.vertex(t, 1)), c(m.vertex(t, 2));
  const glm::dvec3 e1 = b - a, e2 = c - a;
  const glm::dvec3 pv = glm::cross(d, e2);
  const double det = glm::dot(e1, pv);
  if (std::abs(det) < 1e-14) return -1.0;
  const double inv = 1.0 / det;
  const glm::dvec3 tv = p - a;
  const double u = glm::dot(tv, pv) * inv;
  if (u < -1e-9 || u > 1.0 + 1e-9) return -1.0;
  const glm::dvec3 qv = glm::cross(tv, e1);
  const double v = glm::dot(d, qv) * inv;
  if (v < -1e-9 || u + v > 1.0 + 1e-9) return -1.0;
  const double s = glm::dot(e2, qv) * inv;
  return s >= 0.0 && s <= 1.0 ? s : -1.0;
}

// Number of triangles the segment p -> q crosses.
int segmentCrossings(const TriangleMesh& m, glm::dvec3 p, glm::dvec3 q) {
  int hits = 0;
  for (size_t t = 0; t < m.triangleCount(); ++t) hits += segmentHit(m, t, p, q) >= 0.0;
  return hits;
}

// Distance along p -> q to the first of the given triangles, or +inf.
double firstHitDistance(const TriangleMesh& m, const std::vector<size_t>& tris, glm::dvec3 p, glm::dvec3 q) {
  double best = 2.0;
  for (size_t t : tris) {
    const double s = segmentHit(m, t, p, q);
    if (s >= 0.0) best = std::min(best, s);
  }
  return best <= 1.0 ? best * glm::length(q - p) : std::numeric_limits<double>::infinity();
}

// Distance from p (inside b) along unit direction d to b's boundary.
double exitDistance(const Aabb& b, glm::dvec3 p, glm::dvec3 d) {
  double t = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    if (d[k] > 0) t = std::min(t, (double(b.max[k]) - p[k]) / d[k]);
    if (d[k] < 0) t = std::min(t, (double(b.min[k]) - p[k]) / d[k]);
  }
  return t;
}

// Small deterministic generator for test sampling.
struct TestRng {
  uint64_t s;
  uint64_t next() {
    s ^= s << 13;
    s ^= s >> 7;
    s ^= s << 17;
    return s;
  }
  double u01() { return double(next() >> 11) * 0x1.0p-53; }
};

glm::dvec3 randomDirection(TestRng& r) {
  while (true) {
    glm::dvec3 d(2 * r.u01() - 1, 2 * r.u01() - 1, 2 * r.u01() - 1);
    const double l = glm::length(d);
    if (l > 0.1 && l <= 1.0) return d / l;
  }
}

glm::dvec3 randomPointIn(const Aabb& b, double inset, TestRng& r) {
  const glm::dvec3 lo = glm::dvec3(b.min) + inset, hi = glm::dvec3(b.max) - inset;
  return lo + (hi - lo) * glm::dvec3(r.u01(), r.u01(), r.u01());
}

uint32_t bits(float f) {
  return std::bit_cast<uint32_t>(f);
}

bool isTerrain(const TriangleMesh& m, size_t tri) {
  return m.materials[m.triangleMaterial[tri]].category == SurfaceCategory::kTerrain;
}

// (position along the edge, height) bit patterns of the terrain vertices lying exactly on x == edge (or
// z == edge), sorted and de-duplicated.
std::vector<std::pair<uint32_t, uint32_t>> terrainEdge(const TriangleMesh& m, bool alongZ, float edge) {
  std::set<std::pair<uint32_t, uint32_t>> out;
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    if (!isTerrain(m, t)) continue;
    for (int k = 0; k < 3; ++k) {
      const glm::vec3 p = m.vertex(t, k);
      if (alongZ ? p.x == edge : p.z == edge) out.insert({bits(alongZ ? p.z : p.x), bits(p.y)});
    }
  }
  return {out.begin(), out.end()};
}

size_t catCount(const std::vector<size_t>& c, SurfaceCategory k) {
  return c[size_t(k)];
}

TEST(SyntheticWorldParams, RejectsBadParams) {
  auto make = [](double size, double cell) { return SyntheticWorld(WorldParams{1, size, cell}); };
  EXPECT_NO_THROW(make(4096, 64));
  EXPECT_NO_THROW(make(256, 64));
  EXPECT_NO_THROW(make(16, 16));
  EXPECT_NO_THROW(make(1024, 512));
  EXPECT_THROW(make(4096, 15.9), Error);  // cell too small
  EXPECT_THROW(make(4096, 513), Error);   // cell too large
  EXPECT_THROW(make(1000, 64), Error);    // not a multiple
  EXPECT_THROW(make(0, 64), Error);
  EXPECT_THROW(make(-256, 64), Error);
  EXPECT_THROW(make(std::nan(""), 64), Error);
  EXPECT_THROW(make(256, std::numeric_limits<double>::infinity()), Error);
  EXPECT_THROW(make(16.0 * 70000, 16), Error);  // too many cells per axis
  try {
    make(1000, 64);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("multiple"), std::string::npos) << e.what();
  }
}

TEST(SyntheticWorld, OutOfRangeCellsThrow) {
  SyntheticWorld w(WorldParams::smallDefault());
  EXPECT_EQ(w.cellsX(), 4);
  EXPECT_EQ(w.cellsZ(), 4);
  for (CellCoord c :
       {CellCoord{-1, 0}, CellCoord{0, -1}, CellCoord{4, 0}, CellCoord{0, 4}, CellCoord{100, 100}}) {
    EXPECT_THROW(w.generateCell(c), Error);
    EXPECT_THROW(w.describeCell(c), Error);
    EXPECT_THROW(w.cellKind(c), Error);
    EXPECT_THROW(w.cellBounds(c), Error);
  }
  EXPECT_NO_THROW(w.generateCell({3, 3}));
}

TEST(SyntheticDeterminism, SameSeedSameHashInAnyOrderAndInstance) {
  const WorldParams p{7, 4096, 64};
  const std::vector<CellCoord> cells{{0, 0}, {1, 1}, {2, 1}, {1, 2}, {63, 63}, {17, 40}, {40, 17}, {5, 33}};
  SyntheticWorld a(p);
  std::vector<uint64_t> forward;
  for (CellCoord c : cells) forward.push_back(a.generateCell(c).contentHash());
  SyntheticWorld b(p);  // a second instance, reverse order, with other cells generated in between
  std::vector<uint64_t> backward(cells.size());
  for (size_t i = cells.size(); i-- > 0;) {
    b.generateCell({int(i), 9});
    backward[i] = b.generateCell(cells[i]).contentHash();
  }
  EXPECT_EQ(forward, backward);
  // Repeating on the same instance is stable too, and the layout agrees.
  EXPECT_EQ(a.generateCell(cells[2]).contentHash(), forward[2]);
}

TEST(SyntheticDeterminism, DifferentSeedChangesCityCells) {
  SyntheticWorld a(WorldParams::smallDefault(1)), b(WorldParams::smallDefault(2));
  int cityCells = 0;
  for (int z = 0; z < 4; ++z)
    for (int x = 0; x < 4; ++x) {
      if (a.cellKind({x, z}) != CellKind::kCity) continue;
      ++cityCells;
      EXPECT_NE(a.generateCell({x, z}).contentHash(), b.generateCell({x, z}).contentHash()) << x << "," << z;
    }
  EXPECT_GE(cityCells, 4);
}

TEST(SyntheticTerrain, SharedEdgesAreBitIdenticalWithoutTJunctions) {
  // All neighbour pairs of the small world, plus hilly pairs of the 4 km world (found by cell kind).
  struct Case {
    WorldParams p;
    std::vector<CellCoord> cells;
  };
  std::vector<Case> cases;
  {
    Case c{WorldParams::smallDefault(), {}};
    for (int z = 0; z < 4; ++z)
      for (int x = 0; x < 4; ++x) c.cells.push_back({x, z});
    cases.push_back(c);
  }
  {
    Case c{WorldParams{3, 4096, 64}, {}};
    SyntheticWorld w(c.p);
    for (int z = 20; z < 64 && c.cells.size() < 10; z += 7)
      for (int x = 30; x < 63 && c.cells.size() < 10; x += 5)
        if (w.cellKind({x, z}) == CellKind::kField) c.cells.push_back({x, z});
    c.cells.push_back({62, 62});
    cases.push_back(c);
  }
  int hillyEdges = 0, edgesChecked = 0;
  for (const Case& cs : cases) {
    SyntheticWorld w(cs.p);
    const int n = w.terrainQuadsPerCell();
    for (CellCoord c : cs.cells) {
      const TriangleMesh self = w.generateCell(c);
      for (int axis = 0; axis < 2; ++axis) {
        const CellCoord nb = axis == 0 ? CellCoord{c.x + 1, c.z} : CellCoord{c.x, c.z + 1};
        if (!w.contains(nb)) continue;
        const TriangleMesh other = w.generateCell(nb);
        const float edge = axis == 0 ? w.cellBounds(c).max.x : w.cellBounds(c).max.z;
        const auto mine = terrainEdge(self, axis == 0, edge), theirs = terrainEdge(other, axis == 0, edge);
        ASSERT_EQ(mine.size(), size_t(n + 1)) << "cell " << c.x << "," << c.z << " axis " << axis;
        EXPECT_EQ(mine, theirs) << "cell " << c.x << "," << c.z << " axis " << axis;
        ++edgesChecked;
        for (const auto& [pos, h] : mine) hillyEdges += std::bit_cast<float>(h) > 0.5f;
      }
    }
  }
  EXPECT_GT(edgesChecked, 30);
  EXPECT_GT(hillyEdges, 20) << "the test must cover edges with hills, not only flat ground";
}

TEST(SyntheticTerrain, HeightFunctionMatchesTheMeshAndIsFlatInTowns) {
  SyntheticWorld w(WorldParams{5, 4096, 64});
  int hilly = 0;
  for (CellCoord c :
       {CellCoord{10, 50}, CellCoord{33, 33}, CellCoord{60, 3}, CellCoord{1, 1}, CellCoord{47, 12}}) {
    const TriangleMesh m = w.generateCell(c);
    const bool urban = w.cellKind(c) != CellKind::kField;
    for (size_t t = 0; t < m.triangleCount(); ++t) {
      if (!isTerrain(m, t)) continue;
      glm::dvec3 centroid(0.0);
      for (int k = 0; k < 3; ++k) {
        const glm::vec3 p = m.vertex(t, k);
        ASSERT_EQ(bits(w.terrainHeight(p.x, p.z)), bits(p.y)) << p.x << "," << p.z;
        if (urban) {
          ASSERT_EQ(p.y, 0.0f);
        }
        hilly += p.y > 1.0f;
        centroid += glm::dvec3(p) / 3.0;
      }
      ASSERT_NEAR(w.terrainHeight(float(centroid.x), float(centroid.z)), centroid.y, 2e-3);
    }
  }
  EXPECT_GT(hilly, 0);
  EXPECT_EQ(w.terrainHeight(-500.0f, 9000.0f), w.terrainHeight(-500.0f, 9000.0f));  // defined outside too
  // Roads are flat ground.
  for (float x = 0.5f; x < 4096.0f; x += 37.0f)
    EXPECT_EQ(w.terrainHeight(x, 2 * 64 * float(w.mainRoadSpacingCells()) + 1.0f), 0.0f);
}

TEST(SyntheticCells, GeometryStaysInsideItsCell) {
  std::vector<std::pair<WorldParams, std::vector<CellCoord>>> cases;
  {
    std::vector<CellCoord> all;
    for (int z = 0; z < 4; ++z)
      for (int x = 0; x < 4; ++x) all.push_back({x, z});
    cases.push_back({WorldParams::smallDefault(), all});
  }
  {
    TestRng r{99};
    std::vector<CellCoord> some;
    for (int i = 0; i < 40; ++i) some.push_back({int(r.next() % 64), int(r.next() % 64)});
    cases.push_back({WorldParams{11, 4096, 64}, some});
  }
  cases.push_back({WorldParams{4, 1536, 128}, {{3, 3}, {5, 7}, {0, 11}, {11, 0}}});  // 2×2 blocks per cell
  cases.push_back({WorldParams{4, 160, 32}, {{1, 1}, {2, 2}, {4, 4}, {0, 3}}});
  for (const auto& [p, cells] : cases) {
    SyntheticWorld w(p);
    for (CellCoord c : cells) {
      const GeneratedCell g = w.generate(c);
      const Aabb cb = w.cellBounds(c);
      const float tol = 1e-4f;
      for (const glm::vec3& v : g.mesh.positions) {
        ASSERT_GE(v.x, cb.min.x - tol) << "cell " << c.x << "," << c.z << " cellM " << p.cellM;
        ASSERT_LE(v.x, cb.max.x + tol) << "cell " << c.x << "," << c.z << " cellM " << p.cellM;
        ASSERT_GE(v.z, cb.min.z - tol) << "cell " << c.x << "," << c.z << " cellM " << p.cellM;
        ASSERT_LE(v.z, cb.max.z + tol) << "cell " << c.x << "," << c.z << " cellM " << p.cellM;
      }
      EXPECT_LE(g.mesh.bounds().max.y, g.layout.bounds.max.y + tol);
      EXPECT_GE(g.mesh.bounds().min.y, g.layout.bounds.min.y - 0.5f);
    }
  }
}

TEST(SyntheticCells, MeshesAreValidFiniteAndWithinBudget) {
  SyntheticWorld w(WorldParams::smallDefault());
  for (int z = 0; z < 4; ++z)
    for (int x = 0; x < 4; ++x) {
      const TriangleMesh m = w.generateCell({x, z});
      EXPECT_NO_THROW(m.validate("cell"));
      const double area = m.totalArea();
      EXPECT_TRUE(std::isfinite(area));
      EXPECT_GT(area, 0.0);
      EXPECT_LT(m.triangleCount(), 30000u) << x << "," << z;
      EXPECT_GE(m.triangleCount(), size_t(2 * w.terrainQuadsPerCell() * w.terrainQuadsPerCell()));
    }
}

TEST(SyntheticRoads, StripsEndOnTheBorderAndContinueInTheNeighbour) {
  SyntheticWorld w(WorldParams::smallDefault());
  // The main road on line x = 128 runs along z through cells (1, z) | (2, z): check the road vertices on
  // the border z = 64 between (1, 0) and (1, 1) (the -X half strip lies in column 2, the +X half in 1).
  const float line = float(64 * w.mainRoadSpacingCells());
  ASSERT_TRUE(w.isRoad(line - 1.0f, 10.0f));
  ASSERT_TRUE(w.isRoad(line + 1.0f, 10.0f));
  ASSERT_FALSE(w.isRoad(line + 30.0f, 30.0f));
  auto roadOnBorder = [&](CellCoord c, float z) {
    const TriangleMesh m = w.generateCell(c);
    std::set<std::pair<float, float>> out;
    for (size_t t = 0; t < m.triangleCount(); ++t) {
      if (m.materials[m.triangleMaterial[t]].category != SurfaceCategory::kRoad) continue;
      for (int k = 0; k < 3; ++k)
        if (m.vertex(t, k).z == z && m.vertex(t, k).y == kRoadRaiseM)
          out.insert({m.vertex(t, k).x, m.vertex(t, k).y});
    }
    return out;
  };
  for (int column : {1, 2}) {
    const auto below = roadOnBorder({column, 0}, 64.0f), above = roadOnBorder({column, 1}, 64.0f);
    EXPECT_FALSE(below.empty());
    EXPECT_TRUE(below.count({line, kRoadRaiseM}));
    EXPECT_EQ(below, above) << "column " << column;
  }
}

// Descriptors of the 16 cells of the default world.
struct DefaultWorld {
  SyntheticWorld world{WorldParams::smallDefault(1)};
  std::vector<GeneratedCell> cells;
  DefaultWorld() {
    for (int z = 0; z < 4; ++z)
      for (int x = 0; x < 4; ++x) cells.push_back(world.generate({x, z}));
  }
};
const DefaultWorld& defaultWorld() {
  static const DefaultWorld w;
  return w;
}

TEST(SyntheticDefaultWorld, ContainsEveryFeature) {
  const DefaultWorld& dw = defaultWorld();
  int leak = 0, arcades = 0, courtyards = 0, coloured = 0, lamps = 0, litWindows = 0, fields = 0, cities = 0;
  std::vector<size_t> cats(size_t(SurfaceCategory::kCount), 0);
  for (const GeneratedCell& g : dw.cells) {
    const CellLayout& l = g.layout;
    fields += l.kind == CellKind::kField;
    cities += l.kind == CellKind::kCity;
    for (const LeakTestSite& s : l.leakTests) {
      const Room& sealed = l.rooms[size_t(s.sealedRoom)];
      const Room& lit = l.rooms[size_t(s.litRoom)];
      EXPECT_TRUE(sealed.sealed);
      EXPECT_EQ(sealed.openings + sealed.glazedWindows, 0);
      EXPECT_GT(lit.openings, 0);
      EXPECT_FALSE(lit.sealed);
      EXPECT_LE(s.thinWallThicknessM, 0.2f + 1e-6f);
      // The thin wall lies between the rooms: its thickness is their gap, and it spans the sealed room.
      const glm::vec3 ws = s.thinWall.size();
      const float thin = std::min({ws.x, ws.y, ws.z});
      EXPECT_NEAR(thin, s.thinWallThicknessM, 1e-3f);
      const bool alongX = ws.x == thin;
      const float gap = alongX ? std::max(sealed.air.min.x - lit.air.max.x, lit.air.min.x - sealed.air.max.x)
                               : std::max(sealed.air.min.z - lit.air.max.z, lit.air.min.z - sealed.air.max.z);
      EXPECT_NEAR(gap, s.thinWallThicknessM, 1e-3f);
      EXPECT_GE(s.thinWall.max.y, sealed.air.max.y - 1e-3f);
      EXPECT_LE(s.thinWall.min.y, sealed.air.min.y + 1e-3f);
      const glm::vec3 os = s.opening.size();
      EXPECT_GT(os.x * os.y + os.z * os.y, 4.0f) << "the lit room's opening should be big";
      ++leak;
    }
    for (const Arcade& a : l.arcades) {
      EXPECT_GE(a.pillars, 3);
      EXPECT_GT(a.walkway.size().y, 2.5f);
      EXPECT_GE(a.roof.min.y, a.walkway.max.y - 1e-3f);
      ++arcades;
    }
    for (const Courtyard& c : l.courtyards) {
      EXPECT_EQ(c.wings.size(), 4u);
      EXPECT_GT(c.yard.size().x, 10.0f);
      EXPECT_GT(c.yard.size().z, 10.0f);
      EXPECT_FALSE(l.insideSolid((c.yard.min + c.yard.max) * 0.5f));
      ++courtyards;
    }
    for (const ColouredWall& c : l.colouredWalls) {
      const float mx = std::max({c.albedo.r, c.albedo.g, c.albedo.b}),
                  mn = std::min({c.albedo.r, c.albedo.g, c.albedo.b});
      EXPECT_GT(mx, 4.0f * mn);
      ++coloured;
    }
    for (const Emitter& e : l.emitters) {
      const float peak = std::max({e.radiance.r, e.radiance.g, e.radiance.b});
      if (e.kind == EmitterKind::kStreetLamp) {
        EXPECT_GE(peak, 10.0f);
        EXPECT_LE(peak, 1000.0f);
        ++lamps;
      } else {
        EXPECT_GT(peak, 0.5f);
        EXPECT_LT(peak, 10.0f);
        ++litWindows;
      }
      EXPECT_GT(e.areaM2, 0.0f);
    }
    const auto c = g.mesh.categoryTriangleCounts();
    for (size_t k = 0; k < cats.size(); ++k) cats[k] += c[k];
  }
  int overhangs = 0;
  for (const GeneratedCell& g : dw.cells)
    for (const Building& b : g.layout.buildings)
      overhangs += b.roof == RoofKind::kFlatOverhang && b.overhangM >= 0.5f;
  EXPECT_GE(overhangs, 1);
  EXPECT_GE(leak, 1);
  EXPECT_GE(arcades, 1);
  EXPECT_GE(courtyards, 1);
  EXPECT_GE(coloured, 3);
  EXPECT_GE(lamps, 1);
  EXPECT_GE(litWindows, 1);
  EXPECT_GE(fields, 1);
  EXPECT_GE(cities, 1);
  for (SurfaceCategory k :
       {SurfaceCategory::kTerrain, SurfaceCategory::kRoad, SurfaceCategory::kWall, SurfaceCategory::kInterior,
        SurfaceCategory::kRoof, SurfaceCategory::kEmissive, SurfaceCategory::kGlass, SurfaceCategory::kProp})
    EXPECT_GT(catCount(cats, k), 0u) << categoryName(k);
  EXPECT_EQ(catCount(cats, SurfaceCategory::kImported), 0u);
}

TEST(SyntheticDefaultWorld, FieldCellsAreOpen) {
  for (const GeneratedCell& g : defaultWorld().cells) {
    if (g.layout.kind != CellKind::kField) continue;
    EXPECT_TRUE(g.layout.buildings.empty());
    // Nothing but terrain, road strips, lamps along main roads and props lower than 1.6 m above ground.
    for (const SolidBox& s : g.layout.solids) {
      if (s.category == SurfaceCategory::kEmissive) continue;
      const bool lampPart = s.box.size().x < 0.8f && s.box.size().z < 0.8f && s.box.min.y > 4.0f;
      const bool pole = s.box.size().x < 0.2f && s.box.size().z < 0.2f;
      if (lampPart || pole) continue;
      // Props are placed on the highest of 3×3 terrain samples under them, at most 1.2 m tall.
      float ground = -1e30f;
      for (float ax : {0.0f, 0.5f, 1.0f})
        for (float az : {0.0f, 0.5f, 1.0f})
          ground = std::max(ground, defaultWorld().world.terrainHeight(s.box.min.x + ax * s.box.size().x,
                                                                       s.box.min.z + az * s.box.size().z));
      EXPECT_LE(s.box.max.y - ground, 1.6f);
    }
  }
}

// Every leak-test site found: ~50 random segments from inside the sealed room to far outside the building
// each cross at least one triangle, and, stronger, every ray from inside the sealed room (the random ones
// and a 10 cm grid towards all six faces of its air box) hits geometry no later than the room's own
// boundary, so no gap opens anywhere into the neighbouring lit room or outside. The lit room has segments
// to the outside (through its facade opening and its skylight) that cross nothing.
void checkLeakSites(const SyntheticWorld& w, CellCoord c, int& sites) {
  const GeneratedCell g = w.generate(c);
  TestRng r{uint64_t(1000 + c.x * 77 + c.z)};
  for (const LeakTestSite& s : g.layout.leakTests) {
    ++sites;
    const Room& sealed = g.layout.rooms[size_t(s.sealedRoom)];
    Aabb near = g.layout.buildings[size_t(s.building)].bounds;
    near.min -= glm::vec3(0.5f);
    near.max += glm::vec3(0.5f);
    std::vector<size_t> tris;
    for (size_t t = 0; t < g.mesh.triangleCount(); ++t) {
      Aabb tb;
      for (int k = 0; k < 3; ++k) tb.extend(g.mesh.vertex(t, k));
      if (glm::all(glm::lessThanEqual(tb.min, near.max)) && glm::all(glm::greaterThanEqual(tb.max, near.min)))
        tris.push_back(t);
    }
    for (int i = 0; i < 50; ++i) {
      const glm::dvec3 p = randomPointIn(sealed.air, 0.05, r), d = randomDirection(r);
      ASSERT_GE(segmentCrossings(g.mesh, p, p + d * 40.0), 1)
          << "leak from sealed room, cell " << c.x << "," << c.z;
      ASSERT_LE(firstHitDistance(g.mesh, tris, p, p + d * 40.0), exitDistance(sealed.air, p, d) + 1e-3);
    }
    const glm::dvec3 lo(sealed.air.min), hi(sealed.air.max), centre = (lo + hi) * 0.5;
    int gridRays = 0;
    for (int axis = 0; axis < 3; ++axis)
      for (int side = 0; side < 2; ++side) {
        const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
        for (double u = lo[a1] + 0.05; u < hi[a1]; u += 0.1)
          for (double v = lo[a2] + 0.05; v < hi[a2]; v += 0.1) {
            glm::dvec3 q;
            q[axis] = side ? hi[axis] + 0.01 : lo[axis] - 0.01;
            q[a1] = u;
            q[a2] = v;
            ++gridRays;
            ASSERT_LT(firstHitDistance(g.mesh, tris, centre, q), std::numeric_limits<double>::infinity())
                << "gap in the sealed room's boundary towards " << q.x << "," << q.y << "," << q.z;
          }
      }
    EXPECT_GT(gridRays, 5000);
    // Points in the rooms' air are not inside solids.
    const Room& lit = g.layout.rooms[size_t(s.litRoom)];
    for (int i = 0; i < 20; ++i) {
      EXPECT_FALSE(g.layout.insideSolid(glm::vec3(randomPointIn(sealed.air, 0.01, r))));
      EXPECT_FALSE(g.layout.insideSolid(glm::vec3(randomPointIn(lit.air, 0.01, r))));
    }
    const glm::dvec3 litCentre = (glm::dvec3(lit.air.min) + glm::dvec3(lit.air.max)) * 0.5;
    const glm::dvec3 openingCentre = (glm::dvec3(s.opening.min) + glm::dvec3(s.opening.max)) * 0.5;
    const glm::dvec3 outside = openingCentre + glm::dvec3(s.openingNormal) * 2.0;
    EXPECT_EQ(segmentCrossings(g.mesh, litCentre, outside), 0) << "lit room opening is blocked";
    const glm::dvec3 sky = (glm::dvec3(s.skylight.min) + glm::dvec3(s.skylight.max)) * 0.5;
    EXPECT_EQ(segmentCrossings(g.mesh, {sky.x, litCentre.y, sky.z}, sky + glm::dvec3(0, 10, 0)), 0)
        << "skylight blocked";
  }
}

TEST(SyntheticLeakTest, SealedRoomIsClosedAndLitRoomIsOpen) {
  int sites = 0;
  const SyntheticWorld& w = defaultWorld().world;
  for (int z = 0; z < 4; ++z)
    for (int x = 0; x < 4; ++x) checkLeakSites(w, {x, z}, sites);
  EXPECT_GE(sites, 1);
  // Leak-test blocks elsewhere in a 4 km world (other orientations) are sealed as well.
  SyntheticWorld big(WorldParams{1, 4096, 64});
  int bigSites = 0;
  for (int z = 4; z < 64 && bigSites < 3; ++z)
    for (int x = 4; x < 64 && bigSites < 3; x += 3)
      if (big.blockType({x, z}) == BlockType::kLeakTest) checkLeakSites(big, {x, z}, bigSites);
  EXPECT_GE(bigSites, 1);
}

TEST(SyntheticLayout, DescribeMatchesGenerateAndRoomsAreAir) {
  SyntheticWorld w(WorldParams{21, 4096, 64});
  TestRng r{5};
  for (CellCoord c :
       {CellCoord{1, 1}, CellCoord{2, 2}, CellCoord{1, 2}, CellCoord{30, 31}, CellCoord{8, 9}}) {
    const GeneratedCell g = w.generate(c);
    const CellLayout d = w.describeCell(c);
    EXPECT_EQ(d.kind, g.layout.kind);
    ASSERT_EQ(d.solids.size(), g.layout.solids.size());
    for (size_t i = 0; i < d.solids.size(); ++i) {
      EXPECT_EQ(d.solids[i].box.min, g.layout.solids[i].box.min);
      EXPECT_EQ(d.solids[i].box.max, g.layout.solids[i].box.max);
    }
    EXPECT_EQ(d.rooms.size(), g.layout.rooms.size());
    EXPECT_EQ(d.emitters.size(), g.layout.emitters.size());
    EXPECT_EQ(d.buildings.size(), g.layout.buildings.size());
    EXPECT_EQ(d.bounds.max.y, g.layout.bounds.max.y);
    // Emissive triangles are exactly the lamp heads (12 each) and the lit panes (2 each).
    size_t lamps = 0, windows = 0;
    for (const Emitter& e : d.emitters) (e.kind == EmitterKind::kStreetLamp ? lamps : windows)++;
    EXPECT_EQ(g.mesh.categoryTriangleCounts()[size_t(SurfaceCategory::kEmissive)], 12 * lamps + 2 * windows);
    // Room air is free of solids; walls are solid.
    for (const Room& room : d.rooms) {
      for (int i = 0; i < 4; ++i) ASSERT_FALSE(d.insideSolid(glm::vec3(randomPointIn(room.air, 0.01, r))));
      EXPECT_GT(room.air.size().y, 2.0f);
      if (!room.corridor) {
        EXPECT_TRUE(room.sealed || room.openings > 0 || room.glazedWindows > 0);
      }
    }
    for (const Building& b : d.buildings) {
      // Just below the ground-floor level the exterior walls are closed all round (doors start at it).
      const glm::vec3 inWall(b.footprint.min.x + 0.5f * b.wallThicknessM, b.groundFloorY - 0.05f,
                             0.5f * (b.footprint.min.z + b.footprint.max.z));
      EXPECT_TRUE(d.insideSolid(inWall));
    }
  }
}

TEST(SyntheticLayout, SolidsTouchButNeverOverlap) {
  auto check = [](const SyntheticWorld& w, CellCoord c) {
    const CellLayout l = w.describeCell(c);
    const float tol = 1e-3f;
    for (size_t i = 0; i < l.solids.size(); ++i)
      for (size_t j = i + 1; j < l.solids.size(); ++j) {
        const Aabb& a = l.solids[i].box;
        const Aabb& b = l.solids[j].box;
        const glm::vec3 lo = glm::max(a.min, b.min), hi = glm::min(a.max, b.max);
        const bool overlap = hi.x - lo.x > tol && hi.y - lo.y > tol && hi.z - lo.z > tol;
        ASSERT_FALSE(overlap) << "cell " << c.x << "," << c.z << ": solids " << i << " and " << j
                              << " overlap at " << lo.x << "," << lo.y << "," << lo.z << " .. " << hi.x << ","
                              << hi.y << "," << hi.z;
      }
  };
  const SyntheticWorld& dw = defaultWorld().world;
  for (int z = 0; z < 4; ++z)
    for (int x = 0; x < 4; ++x) check(dw, {x, z});
  SyntheticWorld big(WorldParams{8, 4096, 64});
  TestRng r{8};
  for (int i = 0; i < 12; ++i) check(big, {int(r.next() % 64), int(r.next() % 64)});
}

TEST(SyntheticWorld, LargeWorldScattersEveryFeature) {
  SyntheticWorld w(WorldParams{1, 4096, 64});
  int kinds[4] = {0, 0, 0, 0};
  for (int z = 0; z < 64; ++z)
    for (int x = 0; x < 64; ++x) ++kinds[int(w.cellKind({x, z}))];
  EXPECT_GT(kinds[int(CellKind::kField)], 4096 / 5);
  EXPECT_GT(kinds[int(CellKind::kCity)], 4096 / 20);
  EXPECT_GT(kinds[int(CellKind::kSuburb)], 4096 / 20);
  EXPECT_GT(kinds[int(CellKind::kPark)], 0);
  // Outside the showcase corner: describe a sample of cells.
  int leak = 0, arcades = 0, courtyards = 0, coloured = 0, lamps = 0, lit = 0, sealed = 0;
  TestRng r{77};
  for (int i = 0; i < 300; ++i) {
    const CellCoord c{4 + int(r.next() % 60), 4 + int(r.next() % 60)};
    const CellLayout l = w.describeCell(c);
    leak += int(l.leakTests.size());
    arcades += int(l.arcades.size());
    courtyards += int(l.courtyards.size());
    coloured += int(l.colouredWalls.size());
    for (const Emitter& e : l.emitters) (e.kind == EmitterKind::kStreetLamp ? lamps : lit)++;
    for (const Room& room : l.rooms) sealed += room.sealed;
  }
  EXPECT_GT(leak, 0);
  EXPECT_GT(arcades, 0);
  EXPECT_GT(courtyards, 0);
  EXPECT_GT(coloured, 0);
  EXPECT_GT(lamps, 0);
  EXPECT_GT(lit, 0);
  EXPECT_EQ(sealed, leak) << "only leak-test rooms are sealed";
}

// A far corner cell is generated alone, with no other state (speed lives in bench/world_gen, which
// generates every cell and records cells/s and resident memory).
TEST(SyntheticWorld, FarCornerCellAlone) {
  SyntheticWorld w(WorldParams{1, 4096, 64});
  const GeneratedCell g = w.generate({63, 63});
  EXPECT_GT(g.mesh.triangleCount(), 0u);
  EXPECT_EQ(g.layout.cell, (CellCoord{63, 63}));
  EXPECT_EQ(g.mesh.contentHash(),
            SyntheticWorld(WorldParams{1, 4096, 64}).generateCell({63, 63}).contentHash());
}

}  // namespace
}  // namespace lfgi::worlds
