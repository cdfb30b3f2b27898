#version 450
// Cubemap baseline, fragment stage: the G-buffer of one face texel — normal + distance (RGBA32F),
// albedo with coverage in a (RGBA16F), emission (RGBA16F, clamped to the FP16 range: docs/DESIGN.md §2).
#include "shared/cubemap_raster.h"

layout(std430, set = 0, binding = 1) readonly buffer Triangles { CubemapTriangle triangles[]; };

layout(location = 0) in vec3 inOffset;
layout(location = 1) flat in uint inTriangle;

layout(location = 0) out vec4 outNormalDistance;
layout(location = 1) out vec4 outAlbedo;
layout(location = 2) out vec4 outEmission;

void main() {
  CubemapTriangle t = triangles[inTriangle];
  outNormalDistance = vec4(t.normal.xyz, length(inOffset));
  outAlbedo = vec4(t.albedo.rgb, 1.0);
  outEmission = vec4(min(t.emission.rgb, vec3(65504.0)), 0.0);
}
