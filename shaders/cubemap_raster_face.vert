#version 450
// Cubemap baseline, vertex stage: vertex pulling (3 vertices per triangle, no index or vertex-input
// state) and the 90-degree face projection of shared/cubemap_raster.h. Reversed infinite-far depth
// (z_clip = near, w = forward distance): depth = near / forward, compared GREATER, so float depth keeps
// its precision at distance.
#include "shared/cubemap_raster.h"

layout(std430, set = 0, binding = 0) readonly buffer Vertices { vec4 vertices[]; };

layout(push_constant) uniform Push { CubemapRasterParams params; };

layout(location = 0) out vec3 outOffset;       // vertex - probe (m), interpolated for the distance
layout(location = 1) flat out uint outTriangle;  // index into the triangle attribute buffer

void main() {
  vec3 v = vertices[gl_VertexIndex].xyz - params.probe.xyz;
  uint f = params.face;
  gl_Position = vec4(dot(v, cubeFaceRight(f)), dot(v, cubeFaceUp(f)), params.probe.w, dot(v, cubeFaceForward(f)));
  outOffset = v;
  outTriangle = uint(gl_VertexIndex) / 3u;
}
