// Leak control of the probe sources that ship, on worlds/leak_scene.h (a sunlit room | partition | sealed
// room, 1 m probes straddling the partition, placement with relocation as the bake does): the sealed
// room's indirect diffuse over the sunlit room's, Chebyshev visibility on, and the sunlit room's indirect
// light against the Embree capture's (a source that closes the room's openings darkens it). Shading by
// ShadingRenderer (bake/shading_view.h), indirect diffuse only, 6 x 6 floor points per room.
#include <gtest/gtest.h>

#include <cstdio>

#include "bake/embree_scene.h"
#include "bake/probe_sources.h"
#include "bake/shading_inputs.h"
#include "bake/shading_view.h"
#include "gpu/context.h"
#include "worlds/leak_scene.h"
#include "worlds/probe_placement.h"
#include "worlds/sky.h"
#include "worlds/surfels.h"
#include "worlds/triangle_bvh.h"

namespace lfgi::bake {
namespace {

double luminance(glm::vec3 c) {
  return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
}

// Mean indirect diffuse luminance over 6 x 6 floor points of a room.
double roomIndirect(ShadingRenderer& r, const worlds::SkyModel& sky, const worlds::Aabb& air) {
  gpu::GBufferHost g;
  g.height = 1;
  for (int j = 0; j < 6; ++j)
    for (int i = 0; i < 6; ++i) {
      const float x = glm::mix(air.min.x + 0.3f, air.max.x - 0.3f, float(i) / 5.0f);
      const float z = glm::mix(air.min.z + 0.3f, air.max.z - 0.3f, float(j) / 5.0f);
      g.position.push_back(glm::vec4(x, air.min.y + 0.001f, z, 1.0f));
      g.normal.push_back(glm::vec4(0.0f, 1.0f, 0.0f, 1.0f));
      g.albedo.push_back(glm::vec4(0.5f, 0.5f, 0.5f, 0.0f));
      g.emission.push_back(glm::vec4(0.0f));
    }
  g.width = int(g.position.size());
  gpu::ShadingOptions o;
  o.chebyshev = true;
  o.direct = false;
  o.specular = false;
  const gpu::ShadeOutputHost s = r.shadePoints(sky, g, 0.5f * (air.min + air.max), o);
  double sum = 0.0;
  for (const glm::vec4& d : s.diffuse) sum += luminance(glm::vec3(d));
  return sum / double(s.diffuse.size());
}

struct RoomLight {
  double lit = 0.0, dark = 0.0;
  double ratio() const { return lit > 0.0 ? dark / lit : 1.0; }
};

RoomLight shade(ShadingRenderer& r, const ProbeField& f, const worlds::SkyModel& sky,
                const worlds::LeakScene& s) {
  const ProbeField* fp[] = {&f};
  r.setProbes(fp, 1);
  return {roomIndirect(r, sky, s.litAir), roomIndirect(r, sky, s.darkAir)};
}

// VIR probes (the runtime source: relit surfels splatted into every probe) keep the sealed room dark and
// the sunlit room lit, for thin and thick partitions, at the VIR resolution the product uses.
TEST(ProbeLeak, VirProbesKeepTheSealedRoomDarkAndTheSunlitRoomLit) {
  auto ctx = gpu::createContext();
  const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{12.0f, 45.0f, 172, 3.0f, 0.0f});
  for (const float t : {0.05f, 0.1f, 0.5f}) {
    const worlds::LeakScene s = worlds::makeLeakScene(t);
    const EmbreeScene scene(s.mesh, "leak scene");
    const ProbeGrid grid = worlds::leakProbeGrid(s, 1.0f);
    const worlds::TriangleBvh bvh(s.mesh);
    const worlds::PlacedProbes placed = worlds::placeProbes(s.mesh, bvh, grid);
    std::vector<uint8_t> active(placed.flags.size());
    for (size_t i = 0; i < active.size(); ++i)
      active[i] = (placed.flags[i] & worlds::kProbeDisabledSolid) ? 0 : 1;
    CaptureOptions co;
    co.resolution = 8;
    co.irradianceResolution = 4;
    co.samplesPerTexel = 4;
    co.maxBounces = 4;
    const ProbeField cap = captureGridField(scene, sky, grid, placed.offsets, active, co);
    ShadingRenderer renderer(*ctx, s.mesh);
    const RoomLight ref = shade(renderer, cap, sky, s);
    worlds::SurfelOptions so;
    so.spacing = worlds::surfelSpacingForProbeSpacing(grid.spacing.x);
    const std::vector<worlds::Surfel> surfels = worlds::sampleSurfels(s.mesh, so);
    VirProbeOptions vo;
    vo.frames = 6;
    vo.maxRange = 32.0f;
    const ProbeField vir = virProbeField(*ctx, surfels, grid, placed.offsets, active, sky, vo);
    const RoomLight got = shade(renderer, vir, sky, s);
    std::printf(
        "leak t %.2f m: capture lit %.4g dark %.3g ratio %.3g; VIR N=%d lit %.4g dark %.4g ratio %.4f\n",
        double(t), ref.lit, ref.dark, ref.ratio(), vo.resolution, got.lit, got.dark, got.ratio());
    EXPECT_LE(ref.ratio(), 1e-3) << "t " << t;
    EXPECT_LE(got.ratio(), 0.01) << "t " << t;
    EXPECT_GE(got.lit, 0.85 * ref.lit) << "t " << t;
    EXPECT_LE(got.lit, 1.15 * ref.lit) << "t " << t;
  }
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

}  // namespace
}  // namespace lfgi::bake
