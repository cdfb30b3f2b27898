#include "worlds/world_edits.h"

#include <cmath>
#include <cstdlib>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/error.h"

namespace lfgi::worlds {
namespace {

constexpr SurfaceCategory kBoxCategories[] = {SurfaceCategory::kTerrain, SurfaceCategory::kRoad,
                                              SurfaceCategory::kWall,    SurfaceCategory::kInterior,
                                              SurfaceCategory::kRoof,    SurfaceCategory::kProp};

bool boxCategoryAllowed(SurfaceCategory c) {
  for (SurfaceCategory k : kBoxCategories)
    if (k == c) return true;
  return false;
}

std::string boxCategoryList() {
  std::string s;
  for (SurfaceCategory k : kBoxCategories) s += (s.empty() ? "" : ", ") + std::string(categoryName(k));
  return s;
}

void validateOne(const WorldEdit& e, double sizeM, double cellM) {
  const bool box = e.kind == WorldEditKind::kAddBox;
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(e.min[a]) || !std::isfinite(e.max[a]))
      fail("coordinates must be finite numbers (min {},{},{}, max {},{},{})", e.min.x, e.min.y, e.min.z,
           e.max.x, e.max.y, e.max.z);
  if (!(e.max.x > e.min.x && e.max.z > e.min.z))
    fail("zero or negative size: x [{}, {}], z [{}, {}] (need x0 < x1 and z0 < z1)", e.min.x, e.max.x,
         e.min.z, e.max.z);
  if (box && !(e.max.y > e.min.y))
    fail("zero or negative height: y [{}, {}] (need y0 < y1)", e.min.y, e.max.y);
  if (box && e.max.y - e.min.y > 1000.0) fail("box {} m tall; at most 1000 m", e.max.y - e.min.y);
  if (e.min.x < 0.0 || e.min.z < 0.0 || e.max.x > sizeM || e.max.z > sizeM)
    fail("x [{}, {}], z [{}, {}] is not inside the world [0, {}] x [0, {}]", e.min.x, e.max.x, e.min.z,
         e.max.z, sizeM, sizeM);
  switch (e.kind) {
    case WorldEditKind::kAddBuilding: {
      if (e.max.x - e.min.x < 4.0 || e.max.z - e.min.z < 4.0)
        fail("footprint {} m x {} m; a building needs at least 4 m x 4 m", e.max.x - e.min.x,
             e.max.z - e.min.z);
      if (e.storeys < 1 || e.storeys > 40) fail("{} storeys; expected 1..40", e.storeys);
      // Containment: the footprint must lie in one cell's closed range (borders may be touched).
      const double cx = std::floor(e.min.x / cellM), cz = std::floor(e.min.z / cellM);
      if (e.max.x > (cx + 1.0) * cellM)
        fail(
            "footprint x [{}, {}] crosses the cell border x = {} (a building must lie in one cell; move or "
            "split it)",
            e.min.x, e.max.x, (cx + 1.0) * cellM);
      if (e.max.z > (cz + 1.0) * cellM)
        fail(
            "footprint z [{}, {}] crosses the cell border z = {} (a building must lie in one cell; move or "
            "split it)",
            e.min.z, e.max.z, (cz + 1.0) * cellM);
      break;
    }
    case WorldEditKind::kAddBox:
      if (!boxCategoryAllowed(e.category))
        fail("category '{}' is not allowed for a box (allowed: {})", categoryName(e.category),
             boxCategoryList());
      break;
    case WorldEditKind::kClearRegion:
      break;
    default:
      fail("unknown edit kind {}", int(e.kind));
  }
}

std::vector<double> numbersOf(const nlohmann::json& j, const char* field, size_t count) {
  const auto it = j.find(field);
  if (it == j.end() || !it->is_array() || it->size() != count)
    fail("missing or wrong field '{}' (expected an array of {} numbers)", field, count);
  std::vector<double> v;
  for (const auto& x : *it) {
    if (!x.is_number()) fail("field '{}': {} is not a number", field, x.dump());
    v.push_back(x.get<double>());
  }
  return v;
}

}  // namespace

std::string_view worldEditKindName(WorldEditKind k) {
  switch (k) {
    case WorldEditKind::kAddBuilding:
      return "add-building";
    case WorldEditKind::kAddBox:
      return "add-box";
    case WorldEditKind::kClearRegion:
      return "clear-region";
  }
  return "unknown";
}

void validateWorldEdits(const std::vector<WorldEdit>& edits, double sizeM, double cellM) {
  for (size_t i = 0; i < edits.size(); ++i) {
    try {
      validateOne(edits[i], sizeM, cellM);
    } catch (const Error& e) {
      fail("edit {} ({}): {}", i, worldEditKindName(edits[i].kind), e.what());
    }
  }
}

SurfaceCategory parseEditBoxCategory(std::string_view name) {
  for (SurfaceCategory k : kBoxCategories)
    if (categoryName(k) == name) return k;
  fail("box category '{}': expected one of {}", name, boxCategoryList());
}

nlohmann::ordered_json worldEditsToJson(const std::vector<WorldEdit>& edits) {
  nlohmann::ordered_json a = nlohmann::ordered_json::array();
  for (const WorldEdit& e : edits) {
    nlohmann::ordered_json j;
    j["type"] = std::string(worldEditKindName(e.kind));
    switch (e.kind) {
      case WorldEditKind::kAddBuilding:
        j["footprint"] = {e.min.x, e.min.z, e.max.x, e.max.z};
        j["storeys"] = e.storeys;
        break;
      case WorldEditKind::kAddBox:
        j["min"] = {e.min.x, e.min.y, e.min.z};
        j["max"] = {e.max.x, e.max.y, e.max.z};
        j["category"] = std::string(categoryName(e.category));
        break;
      case WorldEditKind::kClearRegion:
        j["region"] = {e.min.x, e.min.z, e.max.x, e.max.z};
        break;
    }
    a.push_back(std::move(j));
  }
  return a;
}

std::vector<WorldEdit> worldEditsFromJson(const nlohmann::json& array) {
  if (!array.is_array()) fail("\"edits\" must be an array");
  std::vector<WorldEdit> out;
  for (size_t i = 0; i < array.size(); ++i) {
    const nlohmann::json& j = array[i];
    try {
      if (!j.is_object() || !j.contains("type") || !j["type"].is_string())
        fail("expected an object with a \"type\" (add-building, add-box or clear-region)");
      const std::string type = j["type"].get<std::string>();
      WorldEdit e;
      if (type == "add-building") {
        e.kind = WorldEditKind::kAddBuilding;
        const std::vector<double> f = numbersOf(j, "footprint", 4);
        e.min = {f[0], 0.0, f[1]};
        e.max = {f[2], 0.0, f[3]};
        if (j.contains("storeys")) {
          if (!j["storeys"].is_number_integer())
            fail("field 'storeys': {} is not an integer", j["storeys"].dump());
          const int64_t s = j["storeys"].get<int64_t>();
          e.storeys = s < -1000 || s > 1000 ? -1 : int(s);
        }
      } else if (type == "add-box") {
        e.kind = WorldEditKind::kAddBox;
        const std::vector<double> lo = numbersOf(j, "min", 3), hi = numbersOf(j, "max", 3);
        e.min = {lo[0], lo[1], lo[2]};
        e.max = {hi[0], hi[1], hi[2]};
        if (j.contains("category")) {
          if (!j["category"].is_string()) fail("field 'category' must be a string");
          e.category = parseEditBoxCategory(j["category"].get<std::string>());
        }
      } else if (type == "clear-region") {
        e.kind = WorldEditKind::kClearRegion;
        const std::vector<double> r = numbersOf(j, "region", 4);
        e.min = {r[0], 0.0, r[1]};
        e.max = {r[2], 0.0, r[3]};
      } else {
        fail("unknown type '{}' (known: add-building, add-box, clear-region)", type);
      }
      out.push_back(e);
    } catch (const Error& e) {
      fail("edit {}: {}", i, e.what());
    }
  }
  return out;
}

WorldEdit parseWorldEdit(WorldEditKind kind, std::string_view text) {
  const std::string flag = fmt::format("--{}", worldEditKindName(kind));
  const char* shape = kind == WorldEditKind::kAddBuilding ? "X0,Z0,X1,Z1[,STOREYS]"
                      : kind == WorldEditKind::kAddBox    ? "X0,Y0,Z0,X1,Y1,Z1[,CATEGORY]"
                                                          : "X0,Z0,X1,Z1";
  std::vector<std::string> items;
  size_t start = 0;
  while (true) {
    const size_t end = text.find(',', start);
    items.emplace_back(
        text.substr(start, end == std::string_view::npos ? std::string_view::npos : end - start));
    if (end == std::string_view::npos) break;
    start = end + 1;
  }
  const size_t coords = kind == WorldEditKind::kAddBox ? 6 : 4;
  const size_t maxItems = kind == WorldEditKind::kClearRegion ? 4 : coords + 1;
  if (items.size() < coords || items.size() > maxItems)
    fail("{} '{}': expected {} ({} items, got {})", flag, text, shape,
         coords == maxItems ? std::to_string(coords) : fmt::format("{} or {}", coords, maxItems),
         items.size());
  std::vector<double> v;
  for (size_t i = 0; i < coords; ++i) {
    const std::string& s = items[i];
    char* end = nullptr;
    const double x = s.empty() ? NAN : std::strtod(s.c_str(), &end);
    if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(x))
      fail("{} '{}': item {} '{}' is not a finite number (expected {})", flag, text, i + 1, s, shape);
    v.push_back(x);
  }
  WorldEdit e;
  e.kind = kind;
  if (kind == WorldEditKind::kAddBox) {
    e.min = {v[0], v[1], v[2]};
    e.max = {v[3], v[4], v[5]};
    if (items.size() == 7) {
      try {
        e.category = parseEditBoxCategory(items[6]);
      } catch (const Error& err) {
        fail("{} '{}': {}", flag, text, err.what());
      }
    }
  } else {
    e.min = {v[0], 0.0, v[1]};
    e.max = {v[2], 0.0, v[3]};
    if (kind == WorldEditKind::kAddBuilding && items.size() == 5) {
      const std::string& s = items[4];
      char* end = nullptr;
      const long n = s.empty() ? 0 : std::strtol(s.c_str(), &end, 10);
      if (s.empty() || end != s.c_str() + s.size() || n < 1 || n > 40)
        fail("{} '{}': storeys '{}' must be an integer in 1..40", flag, text, s);
      e.storeys = int(n);
    }
  }
  return e;
}

}  // namespace lfgi::worlds
