// VIR LOD occlusion test (VirOptions::lodOcclusionRange), included by vir_lod_cut.comp and
// vir_lod_splat.comp for their far pass. The including shader declares `slots` (uint64_t: depth bits << 32
// | node, the splat's depth buffer), `hiz` (uint: per probe map, the max-depth pyramid levels 1, 2, ...
// written by vir_lod_hiz.comp, hizProbeTexels uints each) and `params` (VirLodParams), and includes
// shared/octahedral.h.
//
// virLodOccluded(o, map, centre, radius): true when no surface inside the sphere (centre, radius) can win a
// texel of probe o's map: every texel centre the sphere's image can reach already holds a surface nearer
// than the sphere's nearest point (depth words compare as uints: depths are positive floats and holes
// hold ~0u). The image lies within +- asin(radius / d) x N / 2 x LFGI_VIR_OCT_STRETCH texels of the
// centre's image (the bound vir_lod_splat.comp's window relies on too); a window that reaches the map's
// border may wrap across the fold and is never culled. The test reads <= 2 x 2 texels of the coarsest
// pyramid level whose texels still separate the window's corners. Exact: a culled surface is strictly
// behind every texel it could have won, so culling changes no output bit.

uint virHizLevelDim(uint level) { return (params.res + (1u << level) - 1u) >> level; }

// Index in `hiz` of texel t of pyramid level >= 1 of a probe map.
uint virHizIndex(uint map, uint level, uvec2 t) {
  uint offset = 0u;
  for (uint l = 1u; l < level; ++l) offset += virHizLevelDim(l) * virHizLevelDim(l);
  return map * params.hizProbeTexels + offset + t.y * virHizLevelDim(level) + t.x;
}

uint virHizRead(uint map, uint level, uvec2 t) {
  if (level == 0u) return uint(slots[map * params.res * params.res + t.y * params.res + t.x] >> 32);
  return hiz[virHizIndex(map, level, t)];
}

// The window form: tc the continuous texel coordinates of the centre's image, rho the reach in texels,
// near the sphere's nearest distance.
bool virLodWindowOccluded(uint map, vec2 tc, float rho, float near) {
  if (!(near > 0.0)) return false;  // the probe is inside the sphere
  if (any(lessThan(tc - vec2(rho), vec2(0.0))) || any(greaterThan(tc + vec2(rho), vec2(float(params.res)))))
    return false;
  ivec2 lo = max(ivec2(ceil(tc - vec2(0.5 + rho))), ivec2(0));
  ivec2 hi = min(ivec2(floor(tc + vec2(rho - 0.5))), ivec2(int(params.res) - 1));
  if (any(greaterThan(lo, hi))) return true;  // no texel centre within reach: nothing to splat
  uvec2 ulo = uvec2(lo), uhi = uvec2(hi);
  uint level = 0u;
  while (((uhi.x >> level) - (ulo.x >> level) > 1u || (uhi.y >> level) - (ulo.y >> level) > 1u)) ++level;
  // Margin against rounding in the splat's depth along a texel ray: 1e-5 relative.
  uint nearBits = floatBitsToUint(near * 0.99999);
  uvec2 a = ulo >> level, b = uhi >> level;
  for (uint y = a.y; y <= b.y; ++y)
    for (uint x = a.x; x <= b.x; ++x)
      if (virHizRead(map, level, uvec2(x, y)) >= nearBits) return false;
  return true;
}

bool virLodOccluded(vec3 o, uint map, vec3 centre, float radius) {
  vec3 v = centre - o;
  float d = length(v);
  if (d <= radius * 1.0001 + 1e-6) return false;
  float rho = asin(min(radius / d, 1.0)) * float(params.res) * 0.5 * LFGI_VIR_OCT_STRETCH + 1e-3;
  return virLodWindowOccluded(map, (octEncode(v) * 0.5 + vec2(0.5)) * float(params.res), rho, d - radius);
}
