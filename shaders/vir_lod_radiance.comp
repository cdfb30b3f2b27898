#version 450
// VIR LOD: outgoing radiance of every node of the surfel LOD tree (gpu/vir_lod.h), one level per
// dispatch, leaves first. Leaf: emission + albedo * E / pi (Lambertian, E = its surfel's irradiance, as
// vir_resolve.comp). Inner node: the area-weighted mean of its children's radiance — the radiance a
// texel-sized merged disc must carry so the map's texel averages match the surfels it stands for
// (Christensen 2008); albedo x mean E would be wrong where albedo and E vary together.
#include "shared/surfel.h"
#include "shared/vir.h"

layout(local_size_x = 64, local_size_y = 1, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Nodes { Surfel nodes[]; };
layout(std430, set = 0, binding = 1) readonly buffer Links { VirLodLink links[]; };
layout(std430, set = 0, binding = 2) readonly buffer Children { uint children[]; };
layout(std430, set = 0, binding = 3) readonly buffer Irradiance { vec4 irradiance[]; };  // leaf order
layout(std430, set = 0, binding = 4) buffer NodeRadiance { vec4 nodeRadiance[]; };

layout(push_constant) uniform Push { VirLodParams params; };

void main() {
  if (gl_GlobalInvocationID.x >= params.nodeCount) return;
  uint i = params.nodeFirst + gl_GlobalInvocationID.x;
  if (params.leafPass != 0u) {
    vec3 a = nodes[i].albedo.rgb;
    nodeRadiance[i] = vec4(nodes[i].emission.rgb + a * irradiance[i].rgb * 0.31830988618, 1.0);
    return;
  }
  uint first = links[i].firstChild, count = links[i].childCount;
  vec3 sum = vec3(0.0);
  float area = 0.0;
  for (uint c = 0u; c < count; ++c) {
    uint j = children[first + c];
    float a = max(nodes[j].normal.w, 1e-20);
    sum += a * nodeRadiance[j].rgb;
    area += a;
  }
  nodeRadiance[i] = vec4(sum / max(area, 1e-30), 1.0);
}
