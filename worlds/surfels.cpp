#include "worlds/surfels.h"

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/point_cloud/point_cloud_builder.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>
#include <unordered_map>

#include "core/error.h"
#include "core/half.h"
#include "core/hash.h"

namespace lfgi::worlds {
namespace {

constexpr float kRadiusUnit = 1e-4f;  // radius stored as uint16 in 0.1 mm units (max 6.55 m)

// Our 12-byte header before the Draco stream: magic, version, surfel count. The count lets the decoder
// reject a stream that decodes to a different number of points, and an empty cloud needs no Draco
// stream at all (Draco 1.5 crashes encoding zero points).
constexpr uint32_t kSurfelMagic = 0x4653464cu;  // "LFSF" little-endian
constexpr uint32_t kSurfelVersion = 1;
constexpr size_t kHeaderBytes = 12;
// Decoder limits: a 64 m cell at the finest spacing (0.05 m) holds a few million surfels; the encoder
// spends ~15 bytes per surfel, so 64 per byte is far beyond any real cloud.
constexpr uint32_t kMaxSurfels = uint32_t(1) << 24;
constexpr size_t kMaxSurfelsPerByte = 64;

}  // namespace

float surfelSpacingForProbeSpacing(float probeSpacingM) {
  return std::clamp(probeSpacingM * 0.25f, 0.05f, 2.0f);
}

namespace {

// One sampleSurfels call: the lattice's geometry and the state carried from triangle to triangle.
// Randomness is splitmix64 (core/hash.h), a counter-based hash: each triangle's randomness depends only on
// (seed, triangle index), never on iteration order.
struct SurfelSampler {
  struct PlaneSum {
    double area = 0.0;
    size_t count = 0;
  };

  SurfelSampler(const TriangleMesh& m, const SurfelOptions& o, std::vector<Surfel>& dst)
      : mesh(m), options(o), out(dst), s(o.spacing), cellArea(s * s) {
    out.reserve(size_t(mesh.totalArea() / cellArea * 1.05) + 16);
    // Triangles smaller than one surfel share a running sum (systematic sampling): each gets one surfel of
    // area s^2 when the sum crosses an integer, so their total disc area is within s^2 of their total area
    // (independent coin flips would leave a sqrt(count) s^2 error).
    smallCarry = unitDouble(splitmix64(options.seed ^ 0x5bd1e995ull));
  }

  void sampleTriangle(size_t t);
  uint64_t appendLattice(size_t t, const glm::vec3& n, const glm::vec3& p0, const glm::vec3& p1,
                         const glm::vec3& p2);
  void appendR2(uint64_t hash, int first, int count);
  void emitSurfels(size_t t, const glm::vec3& n, const glm::vec3& p0, const glm::vec3& p1,
                   const glm::vec3& p2, float radius);

  const TriangleMesh& mesh;
  const SurfelOptions& options;
  std::vector<Surfel>& out;
  const double s;
  const double cellArea;
  // Hexagonal lattice of cell area s^2: row pitch h sqrt(3) / 2, point pitch h.
  const double h = s * std::sqrt(2.0 / std::sqrt(3.0)), rowPitch = h * std::sqrt(3.0) * 0.5;
  // R2 sequence (fallback for slivers): generalised golden ratio for 2D (Roberts 2018, "The Unreasonable
  // Effectiveness of Quasirandom Sequences").
  const double g = 1.32471795724474602596;
  const double a1 = 1.0 / g, a2 = 1.0 / (g * g);

  double smallCarry = 0.0;
  std::vector<glm::dvec2> bary;                       // (u, v) of this triangle's surfels
  std::unordered_map<uint64_t, uint32_t> planeIndex;  // lattice key -> planes
  std::vector<PlaneSum> planes;
  std::vector<std::pair<size_t, uint32_t>> surfelPlane;  // (surfel, plane) of lattice surfels
};

// Appends `count` points k = first, first + 1, ... of the R2 sequence offset by `hash`, folded from the
// unit square onto the triangle (uniform in area).
void SurfelSampler::appendR2(uint64_t hash, int first, int count) {
  const double o1 = unitDouble(splitmix64(hash ^ 0x1234567ull)),
               o2 = unitDouble(splitmix64(hash ^ 0x89abcdefull));
  for (int k = first; k < first + count; ++k) {
    const double u = std::fmod(o1 + a1 * k, 1.0), v = std::fmod(o2 + a2 * k, 1.0);
    bary.push_back(u + v > 1.0 ? glm::dvec2(1.0 - u, 1.0 - v) : glm::dvec2(u, v));
  }
}

// Appends triangle t's lattice points to bary; returns its radius group (plane x material).
uint64_t SurfelSampler::appendLattice(size_t t, const glm::vec3& n, const glm::vec3& p0, const glm::vec3& p1,
                                      const glm::vec3& p2) {
  // The lattice lives in the triangle's plane, in coordinates along two in-plane axes measured from the
  // world origin, with an offset hashed from (seed, quantised plane): coplanar triangles (a quad's
  // two halves, a wall of many) share one lattice, so their surfels tile across shared edges.
  const glm::dvec3 nd(n);
  const glm::dvec3 ax = std::abs(nd.y) >= 0.5 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  const glm::dvec3 t1 = glm::normalize(ax - glm::dot(ax, nd) * nd), t2 = glm::cross(nd, t1);
  const glm::dvec3 q0(p0), q1(p1), q2(p2);
  const glm::dvec2 v0(glm::dot(q0, t1), glm::dot(q0, t2)), v1(glm::dot(q1, t1), glm::dot(q1, t2)),
      v2(glm::dot(q2, t1), glm::dot(q2, t2));
  const auto quant = [](double x, double step) { return uint64_t(int64_t(std::llround(x / step))); };
  const uint64_t plane = splitmix64(
      options.seed ^
      splitmix64(quant(nd.x, 1e-4) ^
                 splitmix64(quant(nd.y, 1e-4) ^
                            splitmix64(quant(nd.z, 1e-4) ^ splitmix64(quant(glm::dot(nd, q0), 1e-3))))));
  const uint64_t planeKey = splitmix64(
      plane ^ splitmix64(uint64_t(mesh.triangleMaterial[t]) + 7));  // radius group: plane x material
  const double offX = unitDouble(splitmix64(plane ^ 0x1234567ull)),
               offY = unitDouble(splitmix64(plane ^ 0x89abcdefull));
  const glm::dvec2 lo = glm::min(v0, glm::min(v1, v2)), hi = glm::max(v0, glm::max(v1, v2));
  // Barycentrics of a plane point: p = v0 + u (v1 - v0) + v (v2 - v0).
  const glm::dvec2 e1 = v1 - v0, e2 = v2 - v0;
  const double det = e1.x * e2.y - e1.y * e2.x;
  if (std::abs(det) > 0.0) {
    const long j0 = long(std::ceil(lo.y / rowPitch - offY)), j1 = long(std::floor(hi.y / rowPitch - offY));
    for (long j = j0; j <= j1; ++j) {
      const double y = (double(j) + offY) * rowPitch;
      const double shift = offX + 0.5 * double(j & 1);
      const long i0 = long(std::ceil(lo.x / h - shift)), i1 = long(std::floor(hi.x / h - shift));
      for (long i = i0; i <= i1; ++i) {
        const glm::dvec2 d = glm::dvec2((double(i) + shift) * h, y) - v0;
        const double u = (d.x * e2.y - d.y * e2.x) / det, v = (e1.x * d.y - e1.y * d.x) / det;
        if (u >= 0.0 && v >= 0.0 && u + v <= 1.0) bary.emplace_back(u, v);
      }
    }
  }
  return planeKey;
}

void SurfelSampler::sampleTriangle(size_t t) {
  const double area = mesh.triangleArea(t);
  if (!(area > 0.0)) return;
  const uint64_t h64 = splitmix64(options.seed ^ splitmix64(uint64_t(t) + 1));
  const double expected = area / cellArea;
  const glm::vec3 n = mesh.faceNormal(t);
  const glm::vec3 p0 = mesh.vertex(t, 0), p1 = mesh.vertex(t, 1), p2 = mesh.vertex(t, 2);
  bary.clear();
  bool onLattice = false;
  uint64_t planeKey = 0;
  if (expected >= 1.0) {
    planeKey = appendLattice(t, n, p0, p1, p2);
    onLattice = !bary.empty();
    // A sliver narrower than the lattice: R2 points, as many as its area asks.
    if (bary.empty()) appendR2(h64, 1, int(std::floor(expected + unitDouble(h64))));
  } else {
    const double before = std::floor(smallCarry);
    smallCarry += expected;
    appendR2(h64, 0, int(std::floor(smallCarry) - before));
  }
  if (bary.empty()) return;
  // Radius: small triangles a disc of area s^2; sliver R2 points share the sliver's area; lattice points
  // share the area of their plane's triangles of one material (set below, once all are sampled), so the
  // surfels of a wall have one radius however the triangles' outlines cut the lattice, and an emitter
  // inset in a ceiling keeps its exact area (power).
  const float radius = float(expected < 1.0 ? std::sqrt(cellArea / std::numbers::pi)
                                            : std::sqrt(area / (double(bary.size()) * std::numbers::pi)));
  if (onLattice) {
    auto [it, fresh] = planeIndex.try_emplace(planeKey, uint32_t(planes.size()));
    if (fresh) planes.push_back({0.0, 0});
    planes[it->second].area += area;
    planes[it->second].count += bary.size();
    for (size_t k = 0; k < bary.size(); ++k) surfelPlane.push_back({out.size() + k, it->second});
  }
  emitSurfels(t, n, p0, p1, p2, radius);
}

// Appends one surfel per bary point of triangle t, its albedo from the material's texture where it has one.
void SurfelSampler::emitSurfels(size_t t, const glm::vec3& n, const glm::vec3& p0, const glm::vec3& p1,
                                const glm::vec3& p2, float radius) {
  const Material& mat = mesh.materials[mesh.triangleMaterial[t]];
  const Texture* tex = mat.albedoTexture >= 0 ? &mesh.textures[size_t(mat.albedoTexture)] : nullptr;
  const uint32_t* idx = &mesh.indices[t * 3];
  for (const glm::dvec2& b : bary) {
    const float fu = float(b.x), fv = float(b.y), fw = 1.0f - fu - fv;
    glm::vec3 albedo = mat.albedo;
    if (tex && !mesh.uvs.empty()) {
      glm::vec2 uv = mesh.uvs[idx[0]] * fw + mesh.uvs[idx[1]] * fu + mesh.uvs[idx[2]] * fv;
      albedo *= tex->sampleLinear(uv);
    }
    Surfel sf;
    sf.positionRadius = glm::vec4(p0 * fw + p1 * fu + p2 * fv, radius);
    sf.normal = glm::vec4(n, 0.0f);
    sf.albedo = glm::vec4(glm::clamp(albedo, 0.0f, 1.0f), 1.0f);
    sf.emission = glm::vec4(mat.emission, 0.0f);
    out.push_back(sf);
  }
}

}  // namespace

std::vector<Surfel> sampleSurfels(const TriangleMesh& mesh, const SurfelOptions& options) {
  const double s = options.spacing;
  if (!std::isfinite(s) || s <= 0.0) fail("surfel spacing must be finite and > 0 (got {})", s);
  mesh.validate("surfel sampling input");
  std::vector<Surfel> out;
  SurfelSampler sampler(mesh, options, out);
  for (size_t t = 0; t < mesh.triangleCount(); ++t) sampler.sampleTriangle(t);
  for (const auto& [i, pl] : sampler.surfelPlane)
    out[i].positionRadius.w =
        float(std::sqrt(sampler.planes[pl].area / (double(sampler.planes[pl].count) * std::numbers::pi)));
  return out;
}

double surfelArea(std::span<const Surfel> surfels) {
  double sum = 0.0;
  for (const Surfel& s : surfels)
    sum += std::numbers::pi * double(s.positionRadius.w) * double(s.positionRadius.w);
  return sum;
}

std::vector<std::byte> encodeSurfels(std::span<const Surfel> surfels, int positionBits,
                                     SurfelCodecStats* stats) {
  if (positionBits < 8 || positionBits > 30)
    fail("surfel position bits must be in [8, 30] (got {})", positionBits);
  const size_t n = surfels.size();
  if (n > kMaxSurfels) fail("too many surfels to encode ({}; the decoder's limit is {})", n, kMaxSurfels);
  std::vector<std::byte> bytes(kHeaderBytes);
  const uint32_t header[3] = {kSurfelMagic, kSurfelVersion, uint32_t(n)};
  std::memcpy(bytes.data(), header, kHeaderBytes);
  if (stats) {
    stats->rawBytes = n * 13 * sizeof(float);
    stats->encodedBytes = bytes.size();
  }
  if (n == 0) return bytes;
  std::vector<float> pos(n * 3), nrm(n * 3);
  std::vector<uint8_t> alb(n * 3);
  std::vector<uint16_t> emi(n * 3), rad(n);
  for (size_t i = 0; i < n; ++i) {
    const Surfel& s = surfels[i];
    for (int c = 0; c < 3; ++c) {
      pos[i * 3 + size_t(c)] = s.positionRadius[c];
      nrm[i * 3 + size_t(c)] = s.normal[c];
      alb[i * 3 + size_t(c)] = uint8_t(std::lround(std::clamp(s.albedo[c], 0.0f, 1.0f) * 255.0f));
      emi[i * 3 + size_t(c)] = floatToHalfClamped(s.emission[c]);
    }
    rad[i] = uint16_t(std::clamp(std::lround(s.positionRadius.w / kRadiusUnit), 0l, 65535l));
  }
  draco::PointCloudBuilder builder;
  builder.Start(uint32_t(n));
  int aPos = builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  int aNrm = builder.AddAttribute(draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32);
  int aAlb = builder.AddAttribute(draco::GeometryAttribute::COLOR, 3, draco::DT_UINT8);
  int aEmi = builder.AddAttribute(draco::GeometryAttribute::GENERIC, 3, draco::DT_UINT16);
  int aRad = builder.AddAttribute(draco::GeometryAttribute::GENERIC, 1, draco::DT_UINT16);
  builder.SetAttributeValuesForAllPoints(aPos, pos.data(), 3 * sizeof(float));
  builder.SetAttributeValuesForAllPoints(aNrm, nrm.data(), 3 * sizeof(float));
  builder.SetAttributeValuesForAllPoints(aAlb, alb.data(), 3);
  builder.SetAttributeValuesForAllPoints(aEmi, emi.data(), 3 * sizeof(uint16_t));
  builder.SetAttributeValuesForAllPoints(aRad, rad.data(), sizeof(uint16_t));
  std::unique_ptr<draco::PointCloud> pc = builder.Finalize(false);
  if (!pc) fail("Draco: cannot build a point cloud of {} surfels", n);

  draco::Encoder encoder;
  encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, positionBits);
  encoder.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, 10);
  encoder.SetSpeedOptions(5, 5);
  encoder.SetEncodingMethod(draco::POINT_CLOUD_KD_TREE_ENCODING);
  draco::EncoderBuffer buffer;
  draco::Status status = encoder.EncodePointCloudToBuffer(*pc, &buffer);
  if (!status.ok()) fail("Draco: encoding {} surfels failed: {}", n, status.error_msg_string());
  bytes.resize(kHeaderBytes + buffer.size());
  std::memcpy(bytes.data() + kHeaderBytes, buffer.data(), buffer.size());
  if (stats) stats->encodedBytes = bytes.size();
  return bytes;
}

std::vector<Surfel> decodeSurfels(std::span<const std::byte> bytes, std::string_view what) {
  if (bytes.size() < kHeaderBytes)
    fail("{}: surfel data truncated ({} bytes, header needs {})", what, bytes.size(), kHeaderBytes);
  uint32_t header[3];
  std::memcpy(header, bytes.data(), kHeaderBytes);
  if (header[0] != kSurfelMagic) fail("{}: not lfgi surfel data (bad magic)", what);
  if (header[1] != kSurfelVersion)
    fail("{}: surfel data version {} (this build reads {})", what, header[1], kSurfelVersion);
  const uint32_t count = header[2];
  if (count == 0) {
    if (bytes.size() != kHeaderBytes)
      fail("{}: {} trailing bytes after an empty surfel cloud", what, bytes.size() - kHeaderBytes);
    return {};
  }
  if (bytes.size() == kHeaderBytes)
    fail("{}: surfel data truncated (no Draco stream for {} surfels)", what, count);
  // Draco trusts the point count in its stream and sizes every attribute buffer by it before reading a
  // point, so one flipped bit there asks for gigabytes (found by the seeded bit-flip test: the process was
  // OOM-killed). encodeSurfels always writes the same layout: "DRACO", bitstream 2.x, point cloud (0),
  // kd-tree (1), flags 0 (no metadata), then the int32 point count at byte 11, which must equal ours; and
  // the count is capped and bounded by the stream size before Draco allocates anything.
  const auto* d = reinterpret_cast<const uint8_t*>(bytes.data() + kHeaderBytes);
  const size_t dracoBytes = bytes.size() - kHeaderBytes;
  if (dracoBytes < 15 || std::memcmp(d, "DRACO", 5) != 0)
    fail("{}: corrupt surfel data (no Draco header after the lfgi header)", what);
  if (d[5] != 2 || d[7] != 0 || d[8] != 1 || d[9] != 0 || d[10] != 0)
    fail(
        "{}: corrupt surfel data (Draco bitstream {}.{}, geometry {}, method {}, flags {}; expected a 2.x "
        "kd-tree "
        "point cloud without metadata)",
        what, d[5], d[6], d[7], d[8], int(d[9]) | int(d[10]) << 8);
  int32_t dracoCount = 0;
  std::memcpy(&dracoCount, d + 11, 4);
  if (dracoCount < 0 || uint32_t(dracoCount) != count)
    fail("{}: surfel data holds {} points, header says {}", what, dracoCount, count);
  if (count > kMaxSurfels || count > kMaxSurfelsPerByte * dracoBytes)
    fail("{}: {} surfels in {} bytes of Draco data is corrupt or too many (limits: {}, {} per byte)", what,
         count, dracoBytes, kMaxSurfels, kMaxSurfelsPerByte);
  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(bytes.data() + kHeaderBytes), bytes.size() - kHeaderBytes);
  draco::Decoder decoder;
  auto result = decoder.DecodePointCloudFromBuffer(&buffer);
  if (!result.ok()) fail("{}: corrupt surfel data (Draco: {})", what, result.status().error_msg_string());
  std::unique_ptr<draco::PointCloud> pc = std::move(result).value();
  if (pc->num_points() != count)
    fail("{}: surfel data holds {} points, header says {}", what, pc->num_points(), count);
  const draco::PointAttribute* aPos = pc->GetNamedAttribute(draco::GeometryAttribute::POSITION);
  const draco::PointAttribute* aNrm = pc->GetNamedAttribute(draco::GeometryAttribute::NORMAL);
  const draco::PointAttribute* aAlb = pc->GetNamedAttribute(draco::GeometryAttribute::COLOR);
  const draco::PointAttribute* aEmi = pc->GetNamedAttribute(draco::GeometryAttribute::GENERIC, 0);
  const draco::PointAttribute* aRad = pc->GetNamedAttribute(draco::GeometryAttribute::GENERIC, 1);
  auto expect = [&](const draco::PointAttribute* a, const char* name, int comps, draco::DataType type) {
    if (!a) fail("{}: surfel data lacks the {} attribute", what, name);
    if (a->num_components() != comps || a->data_type() != type)
      fail("{}: surfel {} attribute has {} components of type {}, expected {} of type {}", what, name,
           int(a->num_components()), int(a->data_type()), comps, int(type));
  };
  expect(aPos, "position", 3, draco::DT_FLOAT32);
  expect(aNrm, "normal", 3, draco::DT_FLOAT32);
  expect(aAlb, "albedo", 3, draco::DT_UINT8);
  expect(aEmi, "emission", 3, draco::DT_UINT16);
  expect(aRad, "radius", 1, draco::DT_UINT16);

  std::vector<Surfel> out(pc->num_points());
  for (draco::PointIndex i(0); i < pc->num_points(); ++i) {
    float p[3], nn[3];
    uint8_t al[3];
    uint16_t em[3], r;
    aPos->GetMappedValue(i, p);
    aNrm->GetMappedValue(i, nn);
    aAlb->GetMappedValue(i, al);
    aEmi->GetMappedValue(i, em);
    aRad->GetMappedValue(i, &r);
    Surfel& s = out[i.value()];
    for (float v : {p[0], p[1], p[2], nn[0], nn[1], nn[2]})
      if (!std::isfinite(v)) fail("{}: surfel {} has a non-finite position or normal", what, i.value());
    glm::vec3 normal(nn[0], nn[1], nn[2]);
    float len = glm::length(normal);
    s.positionRadius = glm::vec4(p[0], p[1], p[2], float(r) * kRadiusUnit);
    s.normal = glm::vec4(len > 0.0f ? normal / len : glm::vec3(0.0f, 1.0f, 0.0f), 0.0f);
    s.albedo = glm::vec4(float(al[0]) / 255.0f, float(al[1]) / 255.0f, float(al[2]) / 255.0f, 1.0f);
    s.emission = glm::vec4(halfToFloat(em[0]), halfToFloat(em[1]), halfToFloat(em[2]), 0.0f);
    for (int c = 0; c < 3; ++c)
      if (!std::isfinite(s.emission[c])) fail("{}: surfel {} has a non-finite emission", what, i.value());
  }
  return out;
}

}  // namespace lfgi::worlds
