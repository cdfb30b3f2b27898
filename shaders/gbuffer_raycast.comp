#version 450
// G-buffer by compute ray casting through a flattened BVH (no graphics pipeline): one invocation per
// pixel, camera ray through the pixel centre, first hit's position, viewer-facing normal, material.
#extension GL_GOOGLE_include_directive : require
#include "shared/shading.h"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Params { GBufferParams params; };
layout(std430, set = 0, binding = 1) readonly buffer Nodes { GpuBvhNode nodes[]; };
layout(std430, set = 0, binding = 2) readonly buffer Tris { GpuTriangle tris[]; };
layout(std430, set = 0, binding = 3) readonly buffer Materials { GpuMaterial materials[]; };
layout(std430, set = 0, binding = 4) writeonly buffer OutPosition { vec4 outPosition[]; };
layout(std430, set = 0, binding = 5) writeonly buffer OutNormal { vec4 outNormal[]; };
layout(std430, set = 0, binding = 6) writeonly buffer OutAlbedo { vec4 outAlbedo[]; };
layout(std430, set = 0, binding = 7) writeonly buffer OutEmission { vec4 outEmission[]; };

#include "probe_shade_trace.glsl"

void main() {
  uvec2 id = gl_GlobalInvocationID.xy;
  uvec2 size = params.size.xy;
  if (id.x >= size.x || id.y >= size.y) return;
  uint pixel = id.y * size.x + id.x;
  vec3 o = params.camera.position.xyz;
  vec3 d = cameraRay(params.camera, size, vec2(id) + vec2(0.5));
  float t;
  vec2 bary;
  int hit = params.size.z > 0u ? traceClosest(o, d, 0.0, params.ray.x, t, bary) : -1;
  if (hit < 0) {
    outPosition[pixel] = vec4(d, -1.0);  // miss: xyz holds the ray direction (sky lookup)
    outNormal[pixel] = vec4(0.0);
    outAlbedo[pixel] = vec4(0.0);
    outEmission[pixel] = vec4(0.0);
    return;
  }
  GpuTriangle tri = tris[hit];
  GpuMaterial m = materials[floatBitsToUint(tri.v0.w)];
  vec3 p = tri.v0.xyz + bary.x * tri.e1.xyz + bary.y * tri.e2.xyz;
  vec3 ng = normalize(cross(tri.e1.xyz, tri.e2.xyz));
  bool back = dot(ng, d) > 0.0;
  vec3 n = back ? -ng : ng;
  bool inside = back && m.flags.x == 0.0;
  outPosition[pixel] = vec4(p, t);
  outNormal[pixel] = vec4(n, m.albedo.w);
  outAlbedo[pixel] = vec4(m.albedo.rgb, m.emission.w);
  outEmission[pixel] = vec4(inside ? vec3(0.0) : m.emission.rgb, inside ? 1.0 : 0.0);
}
