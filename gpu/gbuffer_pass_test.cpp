#include "gpu/gbuffer_pass.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <random>

#include "core/error.h"

namespace lfgi::gpu {
namespace {

struct Soup {
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices, material;
  void tri(glm::vec3 a, glm::vec3 b, glm::vec3 c, uint32_t m) {
    const uint32_t i = uint32_t(positions.size());
    positions.insert(positions.end(), {a, b, c});
    indices.insert(indices.end(), {i, i + 1, i + 2});
    material.push_back(m);
  }
};

Soup randomTriangles(int count, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-2.0f, 2.0f), s(-0.3f, 0.3f);
  Soup soup;
  for (int k = 0; k < count; ++k) {
    const glm::vec3 c(u(rng), u(rng), u(rng));
    soup.tri(c + glm::vec3(s(rng), s(rng), s(rng)), c + glm::vec3(s(rng), s(rng), s(rng)),
             c + glm::vec3(s(rng), s(rng), s(rng)), uint32_t(k % 3));
  }
  return soup;
}

std::vector<shared::GpuMaterial> threeMaterials() {
  std::vector<shared::GpuMaterial> m(3);
  for (int k = 0; k < 3; ++k) {
    m[size_t(k)].albedo = glm::vec4(0.1f * float(k + 1), 0.5f, 0.7f, 1.0f);
    m[size_t(k)].emission = glm::vec4(float(k), 0.0f, 0.0f, 0.0f);
    m[size_t(k)].flags = glm::vec4(k == 2 ? 1.0f : 0.0f, 0.0f, 0.0f, 0.0f);
  }
  return m;
}

float bruteForce(const Soup& s, glm::vec3 o, glm::vec3 d, int& hit) {
  float best = 1e30f;
  hit = -1;
  for (size_t t = 0; t < s.material.size(); ++t) {
    const glm::vec3 v0 = s.positions[s.indices[t * 3]], e1 = s.positions[s.indices[t * 3 + 1]] - v0,
                    e2 = s.positions[s.indices[t * 3 + 2]] - v0;
    const glm::vec3 p = glm::cross(d, e2);
    const float det = glm::dot(e1, p);
    if (std::abs(det) < 1e-20f) continue;
    const glm::vec3 q0 = o - v0;
    const float u = glm::dot(q0, p) / det;
    const glm::vec3 q = glm::cross(q0, e1);
    const float v = glm::dot(d, q) / det;
    const float tt = glm::dot(e2, q) / det;
    if (u >= 0.0f && v >= 0.0f && u + v <= 1.0f && tt > 0.0f && tt < best) {
      best = tt;
      hit = int(t);
    }
  }
  return best;
}

TEST(GpuScene, BvhClosestHitEqualsBruteForce) {
  const Soup soup = randomTriangles(600, 7);
  const GpuScene scene = buildGpuScene(soup.positions, soup.indices, soup.material, threeMaterials());
  ASSERT_EQ(scene.triangles.size(), 600u);
  EXPECT_GT(scene.nodes.size(), 100u);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  int hits = 0;
  for (int k = 0; k < 3000; ++k) {
    const glm::vec3 o(3.0f * u(rng), 3.0f * u(rng), 3.0f * u(rng));
    const glm::vec3 d = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(1e-3f));
    int want = -1;
    const float tWant = bruteForce(soup, o, d, want);
    float t = 0.0f;
    const int got = intersectGpuScene(scene, o, d, 1e30f, t);
    ASSERT_EQ(got < 0, want < 0) << "ray " << k;
    if (got >= 0) {
      ++hits;
      EXPECT_NEAR(t, tWant, 1e-5f * (1.0f + tWant)) << "ray " << k;
      const uint32_t original = std::bit_cast<uint32_t>(scene.triangles[size_t(got)].e1.w);
      EXPECT_EQ(scene.triangles[size_t(got)].v0.w, std::bit_cast<float>(soup.material[original]));
    }
  }
  EXPECT_GT(hits, 300);
}

TEST(GpuScene, BadInputIsAnError) {
  const std::vector<glm::vec3> p{glm::vec3(0.0f), glm::vec3(1.0f, 0.0f, 0.0f), glm::vec3(0.0f, 1.0f, 0.0f)};
  const std::vector<uint32_t> idx{0, 1, 3}, mat{0};
  EXPECT_THROW(buildGpuScene(p, idx, mat, threeMaterials()), Error);
  const std::vector<uint32_t> idxOk{0, 1, 2}, matBad{5};
  EXPECT_THROW(buildGpuScene(p, idxOk, matBad, threeMaterials()), Error);
  const GpuScene empty = buildGpuScene({}, {}, {}, {});
  float t = 0.0f;
  EXPECT_EQ(intersectGpuScene(empty, glm::vec3(0.0f), glm::vec3(0.0f, 1.0f, 0.0f), 1e30f, t), -1);
  EXPECT_THROW(makeGpuCamera(glm::vec3(0.0f), glm::vec3(0.0f, 2.0f, 0.0f), 60.0f, 4, 4), Error);
}

// The device ray cast against the CPU traversal of the same flattened data, pixel by pixel.
TEST(GBufferPass, RayCastMatchesTheCpuTraversal) {
  Soup soup = randomTriangles(300, 11);
  // A closed room around everything (material 0: single-sided, inward) so most rays hit something.
  const float h = 4.0f;
  const glm::vec3 c[8] = {{-h, -h, -h}, {h, -h, -h}, {-h, h, -h}, {h, h, -h},
                          {-h, -h, h},  {h, -h, h},  {-h, h, h},  {h, h, h}};
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    soup.tri(c[q[0]], c[q[1]], c[q[2]], 0);
    soup.tri(c[q[0]], c[q[2]], c[q[3]], 0);
  }
  const GpuScene scene = buildGpuScene(soup.positions, soup.indices, soup.material, threeMaterials());
  auto ctx = createContext();
  const GpuSceneBuffers buffers = uploadGpuScene(*ctx, scene);
  const int w = 40, hgt = 30;
  const glm::vec3 eye(0.3f, 0.2f, 3.5f);
  const shared::GpuCamera cam = makeGpuCamera(eye, glm::vec3(0.0f), 70.0f, w, hgt);
  GBufferPass pass(*ctx);
  pass.setCamera(cam, w, hgt, buffers);
  GBuffer g = createGBuffer(*ctx, w, hgt);
  submitAndWait(*ctx, [&](VkCommandBuffer cmd) { pass.record(cmd, buffers, g); });
  const GBufferHost host = readGBuffer(*ctx, g);
  int compared = 0;
  for (int y = 0; y < hgt; ++y) {
    for (int x = 0; x < w; ++x) {
      const float sx = (2.0f * (float(x) + 0.5f) / float(w) - 1.0f) * cam.position.w * cam.forward.w;
      const float sy = (1.0f - 2.0f * (float(y) + 0.5f) / float(hgt)) * cam.position.w;
      const glm::vec3 d =
          glm::normalize(glm::vec3(cam.forward) + sx * glm::vec3(cam.right) + sy * glm::vec3(cam.up));
      float t = 0.0f;
      const int k = intersectGpuScene(scene, eye, d, 1e4f, t);
      const size_t p = size_t(y) * size_t(w) + size_t(x);
      ASSERT_GE(k, 0);  // the room closes every ray
      EXPECT_NEAR(host.position[p].w, t, 1e-4f * (1.0f + t)) << x << "," << y;
      const glm::vec3 hitP = eye + t * d;
      EXPECT_LT(glm::length(glm::vec3(host.position[p]) - hitP), 1e-3f);
      EXPECT_LT(glm::dot(glm::vec3(host.normal[p]), d), 0.0f);  // faces the viewer
      const uint32_t mat = std::bit_cast<uint32_t>(scene.triangles[size_t(k)].v0.w);
      EXPECT_FLOAT_EQ(host.albedo[p].x, scene.materials[mat].albedo.x);
      ++compared;
    }
  }
  EXPECT_EQ(compared, w * hgt);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

}  // namespace
}  // namespace lfgi::gpu
