#include "gpu/gbuffer_pass.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <numbers>

#include "core/error.h"

namespace lfgi::gpu {
namespace {

constexpr uint32_t kLeafSize = 4;
constexpr int kBins = 12;
constexpr int kMaxDepth = 40;

struct BuildTri {
  glm::vec3 lo, hi, centroid;
  uint32_t index;
};

float boxArea(glm::vec3 lo, glm::vec3 hi) {
  const glm::vec3 d = glm::max(hi - lo, glm::vec3(0.0f));
  return 2.0f * (d.x * d.y + d.y * d.z + d.z * d.x);
}

struct Builder {
  std::vector<BuildTri> tris;
  std::vector<shared::GpuBvhNode> nodes;

  uint32_t build(uint32_t begin, uint32_t end, int depth) {
    glm::vec3 lo(1e30f), hi(-1e30f), clo(1e30f), chi(-1e30f);
    for (uint32_t i = begin; i < end; ++i) {
      lo = glm::min(lo, tris[i].lo);
      hi = glm::max(hi, tris[i].hi);
      clo = glm::min(clo, tris[i].centroid);
      chi = glm::max(chi, tris[i].centroid);
    }
    const uint32_t self = uint32_t(nodes.size());
    nodes.push_back({glm::vec4(lo, 0.0f), glm::vec4(hi, 0.0f)});
    const uint32_t count = end - begin;
    auto makeLeaf = [&] {
      nodes[self].lo.w = std::bit_cast<float>(begin);
      nodes[self].hi.w = std::bit_cast<float>(count);
      return self;
    };
    const glm::vec3 extent = chi - clo;
    if (count <= kLeafSize || std::max({extent.x, extent.y, extent.z}) <= 0.0f) return makeLeaf();

    // Binned SAH over the centroid box; median split on the longest axis when too deep or no good split.
    int bestAxis = -1, bestBin = -1;
    float bestCost = float(count) * boxArea(lo, hi);
    if (depth < kMaxDepth) {
      for (int axis = 0; axis < 3; ++axis) {
        if (extent[axis] <= 0.0f) continue;
        glm::vec3 blo[kBins], bhi[kBins];
        uint32_t bcount[kBins] = {};
        for (int b = 0; b < kBins; ++b) blo[b] = glm::vec3(1e30f), bhi[b] = glm::vec3(-1e30f);
        const float scale = float(kBins) / extent[axis];
        for (uint32_t i = begin; i < end; ++i) {
          const int b = std::min(kBins - 1, int((tris[i].centroid[axis] - clo[axis]) * scale));
          ++bcount[b];
          blo[b] = glm::min(blo[b], tris[i].lo);
          bhi[b] = glm::max(bhi[b], tris[i].hi);
        }
        float rightArea[kBins];
        uint32_t rightCount[kBins];
        glm::vec3 rlo(1e30f), rhi(-1e30f);
        uint32_t rc = 0;
        for (int b = kBins - 1; b > 0; --b) {
          rlo = glm::min(rlo, blo[b]);
          rhi = glm::max(rhi, bhi[b]);
          rc += bcount[b];
          rightArea[b] = boxArea(rlo, rhi);
          rightCount[b] = rc;
        }
        glm::vec3 llo(1e30f), lhi(-1e30f);
        uint32_t lc = 0;
        for (int b = 0; b < kBins - 1; ++b) {
          llo = glm::min(llo, blo[b]);
          lhi = glm::max(lhi, bhi[b]);
          lc += bcount[b];
          if (lc == 0 || rightCount[b + 1] == 0) continue;
          const float cost = float(lc) * boxArea(llo, lhi) + float(rightCount[b + 1]) * rightArea[b + 1];
          if (cost < bestCost) {
            bestCost = cost;
            bestAxis = axis;
            bestBin = b;
          }
        }
      }
    }
    uint32_t mid;
    if (bestAxis >= 0) {
      const float scale = float(kBins) / extent[bestAxis];
      auto it = std::partition(tris.begin() + begin, tris.begin() + end, [&](const BuildTri& t) {
        return std::min(kBins - 1, int((t.centroid[bestAxis] - clo[bestAxis]) * scale)) <= bestBin;
      });
      mid = uint32_t(it - tris.begin());
    } else if (count <= 2 * kLeafSize && depth < kMaxDepth) {
      return makeLeaf();  // splitting costs more than testing these few triangles
    } else {
      const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
      mid = begin + count / 2;
      std::nth_element(tris.begin() + begin, tris.begin() + mid, tris.begin() + end,
                       [&](const BuildTri& a, const BuildTri& b) {
                         return a.centroid[axis] < b.centroid[axis] ||
                                (a.centroid[axis] == b.centroid[axis] && a.index < b.index);
                       });
    }
    if (mid == begin || mid == end) mid = begin + count / 2;
    build(begin, mid, depth + 1);
    const uint32_t right = build(mid, end, depth + 1);
    nodes[self].lo.w = std::bit_cast<float>(right);
    nodes[self].hi.w = std::bit_cast<float>(0u);
    return self;
  }
};

bool rayBox(glm::vec3 lo, glm::vec3 hi, glm::vec3 o, glm::vec3 inv, float tMax) {
  const glm::vec3 t0 = (lo - o) * inv, t1 = (hi - o) * inv;
  const glm::vec3 tn = glm::min(t0, t1), tf = glm::max(t0, t1);
  const float enter = std::max({tn.x, tn.y, tn.z, 0.0f});
  const float leave = std::min({tf.x, tf.y, tf.z, tMax});
  return enter <= leave;
}

}  // namespace

GpuScene buildGpuScene(std::span<const glm::vec3> positions, std::span<const uint32_t> indices,
                       std::span<const uint32_t> triangleMaterial,
                       std::vector<shared::GpuMaterial> materials) {
  if (indices.size() % 3 != 0) fail("GPU scene: {} indices is not a multiple of 3", indices.size());
  const size_t n = indices.size() / 3;
  if (triangleMaterial.size() != n)
    fail("GPU scene: {} triangle materials for {} triangles", triangleMaterial.size(), n);
  Builder b;
  b.tris.reserve(n);
  for (size_t t = 0; t < n; ++t) {
    if (triangleMaterial[t] >= materials.size())
      fail("GPU scene: triangle {} has material {} of {}", t, triangleMaterial[t], materials.size());
    BuildTri bt{glm::vec3(1e30f), glm::vec3(-1e30f), glm::vec3(0.0f), uint32_t(t)};
    for (int k = 0; k < 3; ++k) {
      const uint32_t i = indices[t * 3 + size_t(k)];
      if (i >= positions.size())
        fail("GPU scene: triangle {} index {} >= {} positions", t, i, positions.size());
      const glm::vec3 p = positions[i];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        fail("GPU scene: position {} is not finite", i);
      bt.lo = glm::min(bt.lo, p);
      bt.hi = glm::max(bt.hi, p);
    }
    bt.centroid = 0.5f * (bt.lo + bt.hi);
    b.tris.push_back(bt);
  }
  GpuScene scene;
  if (n == 0) {
    scene.nodes.push_back({glm::vec4(1e30f, 1e30f, 1e30f, 0.0f), glm::vec4(-1e30f, -1e30f, -1e30f, 0.0f)});
  } else {
    b.build(0, uint32_t(n), 0);
    scene.nodes = std::move(b.nodes);
  }
  scene.triangles.reserve(n);
  for (const BuildTri& bt : b.tris) {
    const size_t t = bt.index;
    const glm::vec3 v0 = positions[indices[t * 3]], v1 = positions[indices[t * 3 + 1]],
                    v2 = positions[indices[t * 3 + 2]];
    scene.triangles.push_back({glm::vec4(v0, std::bit_cast<float>(triangleMaterial[t])),
                               glm::vec4(v1 - v0, std::bit_cast<float>(uint32_t(t))),
                               glm::vec4(v2 - v0, 0.0f)});
  }
  if (materials.empty()) materials.push_back({});
  scene.materials = std::move(materials);
  return scene;
}

int intersectGpuScene(const GpuScene& scene, glm::vec3 o, glm::vec3 d, float tMax, float& tHit) {
  glm::vec3 inv;
  for (int k = 0; k < 3; ++k) inv[k] = 1.0f / (d[k] == 0.0f ? 1e-12f : d[k]);
  int best = -1;
  tHit = tMax;
  if (scene.triangles.empty()) return best;  // the lone empty node is not a leaf (count 0)
  std::vector<uint32_t> stack{0};
  while (!stack.empty()) {
    const uint32_t ni = stack.back();
    stack.pop_back();
    const shared::GpuBvhNode& nd = scene.nodes[ni];
    if (!rayBox(glm::vec3(nd.lo), glm::vec3(nd.hi), o, inv, tHit)) continue;
    const uint32_t count = std::bit_cast<uint32_t>(nd.hi.w), ref = std::bit_cast<uint32_t>(nd.lo.w);
    if (count == 0) {
      stack.push_back(ref);
      stack.push_back(ni + 1);
      continue;
    }
    for (uint32_t k = ref; k < ref + count; ++k) {
      const shared::GpuTriangle& tri = scene.triangles[k];
      const glm::vec3 e1(tri.e1), e2(tri.e2);
      const glm::vec3 p = glm::cross(d, e2);
      const float det = glm::dot(e1, p);
      if (std::abs(det) < 1e-20f) continue;
      const float invDet = 1.0f / det;
      const glm::vec3 s = o - glm::vec3(tri.v0);
      const float u = glm::dot(s, p) * invDet;
      if (u < 0.0f || u > 1.0f) continue;
      const glm::vec3 q = glm::cross(s, e1);
      const float v = glm::dot(d, q) * invDet;
      if (v < 0.0f || u + v > 1.0f) continue;
      const float t = glm::dot(e2, q) * invDet;
      if (t > 0.0f && t < tHit) {
        tHit = t;
        best = int(k);
      }
    }
  }
  return best;
}

GpuSceneBuffers uploadGpuScene(Context& ctx, const GpuScene& scene) {
  GpuSceneBuffers b;
  b.nodeCount = uint32_t(scene.nodes.size());
  b.triangleCount = uint32_t(scene.triangles.size());
  b.nodes = createStorageBuffer(ctx, std::max<size_t>(1, scene.nodes.size()) * sizeof(shared::GpuBvhNode));
  b.triangles =
      createStorageBuffer(ctx, std::max<size_t>(1, scene.triangles.size()) * sizeof(shared::GpuTriangle));
  b.materials =
      createStorageBuffer(ctx, std::max<size_t>(1, scene.materials.size()) * sizeof(shared::GpuMaterial));
  upload<shared::GpuBvhNode>(ctx, b.nodes, scene.nodes);
  if (!scene.triangles.empty()) upload<shared::GpuTriangle>(ctx, b.triangles, scene.triangles);
  if (!scene.materials.empty()) upload<shared::GpuMaterial>(ctx, b.materials, scene.materials);
  return b;
}

shared::GpuCamera makeGpuCamera(glm::vec3 position, glm::vec3 target, float fovDeg, int width, int height) {
  const glm::vec3 d = target - position;
  const float len = glm::length(d);
  if (!(len > 0.0f) || std::abs(d.y) / len > 0.99999f || !(fovDeg > 0.0f && fovDeg < 180.0f) || width < 1 ||
      height < 1)
    fail(
        "camera: position, target, fov {} deg or size {}x{} unusable (target must differ from the position "
        "and not lie straight above or below it)",
        fovDeg, width, height);
  const glm::vec3 forward = d / len;
  const glm::vec3 right = glm::normalize(glm::cross(forward, glm::vec3(0.0f, 1.0f, 0.0f)));
  const glm::vec3 up = glm::cross(right, forward);
  const float tanHalf = std::tan(0.5f * fovDeg * std::numbers::pi_v<float> / 180.0f);
  return {glm::vec4(position, tanHalf), glm::vec4(forward, float(width) / float(height)),
          glm::vec4(right, 0.0f), glm::vec4(up, 0.0f)};
}

GBuffer createGBuffer(Context& ctx, int width, int height) {
  if (width < 1 || height < 1) fail("G-buffer: size {}x{} must be at least 1x1", width, height);
  GBuffer g;
  g.width = width;
  g.height = height;
  const VkDeviceSize bytes = VkDeviceSize(width) * VkDeviceSize(height) * sizeof(glm::vec4);
  g.position = createStorageBuffer(ctx, bytes);
  g.normal = createStorageBuffer(ctx, bytes);
  g.albedo = createStorageBuffer(ctx, bytes);
  g.emission = createStorageBuffer(ctx, bytes);
  return g;
}

GBufferHost readGBuffer(Context& ctx, const GBuffer& g) {
  GBufferHost h;
  h.width = g.width;
  h.height = g.height;
  const size_t n = size_t(g.width) * size_t(g.height);
  for (auto [dst, src] : {std::pair{&h.position, &g.position}, std::pair{&h.normal, &g.normal},
                          std::pair{&h.albedo, &g.albedo}, std::pair{&h.emission, &g.emission}}) {
    dst->resize(n);
    readback<glm::vec4>(ctx, *src, *dst);
  }
  return h;
}

void writeGBuffer(Context& ctx, const GBufferHost& h, GBuffer& g) {
  const size_t n = size_t(g.width) * size_t(g.height);
  if (h.width != g.width || h.height != g.height || h.position.size() != n || h.normal.size() != n ||
      h.albedo.size() != n || h.emission.size() != n)
    fail("G-buffer upload: host data {}x{} does not match the {}x{} G-buffer", h.width, h.height, g.width,
         g.height);
  upload<glm::vec4>(ctx, g.position, h.position);
  upload<glm::vec4>(ctx, g.normal, h.normal);
  upload<glm::vec4>(ctx, g.albedo, h.albedo);
  upload<glm::vec4>(ctx, g.emission, h.emission);
}

GBufferPass::GBufferPass(Context& ctx)
    : ctx_(ctx),
      program_(ctx, "gbuffer_raycast"),
      params_(createStorageBuffer(ctx, sizeof(shared::GBufferParams))) {}

namespace {

shared::GBufferParams cameraParams(const shared::GpuCamera& camera, int width, int height,
                                   const GpuSceneBuffers& scene, float maxDistance) {
  shared::GBufferParams p{};
  p.camera = camera;
  p.size = glm::uvec4(uint32_t(width), uint32_t(height), scene.triangleCount > 0 ? scene.nodeCount : 0u,
                      scene.triangleCount);
  p.ray = glm::vec4(maxDistance, 0.0f, 0.0f, 0.0f);
  return p;
}

}  // namespace

void GBufferPass::setCamera(const shared::GpuCamera& camera, int width, int height,
                            const GpuSceneBuffers& scene, float maxDistance) {
  const shared::GBufferParams p = cameraParams(camera, width, height, scene, maxDistance);
  upload<shared::GBufferParams>(ctx_, params_, std::span(&p, 1));
}

void GBufferPass::recordCamera(VkCommandBuffer cmd, const shared::GpuCamera& camera, int width, int height,
                               const GpuSceneBuffers& scene, float maxDistance) {
  const shared::GBufferParams p = cameraParams(camera, width, height, scene, maxDistance);
  recordBufferUpdate(cmd, params_, std::as_bytes(std::span(&p, 1)));
}

void GBufferPass::record(VkCommandBuffer cmd, const GpuSceneBuffers& scene, GBuffer& g) const {
  dispatch(ctx_, cmd, program_,
           {&params_, &scene.nodes, &scene.triangles, &scene.materials, &g.position, &g.normal, &g.albedo,
            &g.emission},
           std::span<const std::byte>(), {uint32_t(g.width), uint32_t(g.height), 1});
}

}  // namespace lfgi::gpu
