#version 450
// Shading a G-buffer from light-field probes. Per pixel: the 8 probes around the point (taken from
// whichever cell owns each lattice point, so shading crosses cell borders), weighted by trilinear x
// Chebyshev visibility from the probes' distance moments x backface weight, as in McGuire et al. 2017
// ("Real-Time Global Illumination using Precomputed Light Field Probes") and Majercik et al. 2019
// ("Dynamic Diffuse Global Illumination with Ray-Traced Irradiance Fields", JCGT 8(2), listing 4:
// normal/view bias, wrap-shading backface weight, the 0.2 crush of tiny weights).
// Indirect diffuse = diffuse BRDF x bilinear octahedral irradiance; indirect specular = GGX-prefiltered
// radiance at the mirror direction (roughness levels interpolated) x split-sum environment BRDF (Karis
// 2014 analytic fit); direct = emission + sun/moon with a shadow ray through the same BVH; escaped rays
// show the sky and the discs. Optional ambient occlusion (params.weights.w = radius) from short rays
// through the BVH multiplies the indirect diffuse.
// Streaming fallback (gpu/probe_shading_pass.h): cells are full (probes, with a fade) or fallback-only (SH
// L1); the probes' share of a point is beta = sum of trilinear x fade over its corners, the rest comes
// from the fallback, bilinear between the cell centres around it (StreamingManager::sample()).
#extension GL_GOOGLE_include_directive : require
#include "shared/octahedral.h"
#include "shared/shading.h"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Params { ShadeParams params; };
layout(std430, set = 0, binding = 1) readonly buffer Cells { ShadeCell cells[]; };
layout(std430, set = 0, binding = 2) readonly buffer Probes { vec4 probes[]; };
layout(std430, set = 0, binding = 3) readonly buffer Irradiance { vec4 irradiance[]; };
layout(std430, set = 0, binding = 4) readonly buffer Distance { vec2 moments[]; };
layout(std430, set = 0, binding = 5) readonly buffer Specular { vec4 specular[]; };
layout(std430, set = 0, binding = 6) readonly buffer Nodes { GpuBvhNode nodes[]; };
layout(std430, set = 0, binding = 7) readonly buffer Tris { GpuTriangle tris[]; };
layout(std430, set = 0, binding = 8) readonly buffer GPosition { vec4 gPosition[]; };
layout(std430, set = 0, binding = 9) readonly buffer GNormal { vec4 gNormal[]; };
layout(std430, set = 0, binding = 10) readonly buffer GAlbedo { vec4 gAlbedo[]; };
layout(std430, set = 0, binding = 11) readonly buffer GEmission { vec4 gEmission[]; };
layout(std430, set = 0, binding = 12) writeonly buffer ODirect { vec4 outDirect[]; };
layout(std430, set = 0, binding = 13) writeonly buffer ODiffuse { vec4 outDiffuse[]; };
layout(std430, set = 0, binding = 14) writeonly buffer OSpecular { vec4 outSpecular[]; };
layout(std430, set = 0, binding = 15) writeonly buffer OTotal { vec4 outTotal[]; };

#include "probe_shade_trace.glsl"

const float kPi = 3.14159265358979;

// Bilinear tap positions of direction d in a bordered octahedral map of interior resolution r, as the
// CPU's octSampleBilinear (core/octahedral.cpp): b is the bordered texel coordinate with bordered texel i's
// centre at b = i (interior texel j, centre (j + 0.5) / r in encode space, is bordered texel j + 1).
void octBilinear(vec3 d, uint r, out uvec2 t0, out vec2 f) {
  vec2 b = (octEncode(d) * 0.5 + vec2(0.5)) * float(r) + vec2(0.5);
  vec2 x0 = clamp(floor(b), vec2(0.0), vec2(float(r)));
  f = clamp(b - x0, vec2(0.0), vec2(1.0));
  t0 = uvec2(x0);
}

vec3 sampleIrradiance(uint probe, vec3 d) {
  uint r = params.maps.x, rb = r + 2u;
  uvec2 t;
  vec2 f;
  octBilinear(d, r, t, f);
  uint base = probe * rb * rb + t.y * rb + t.x;
  vec3 a = mix(irradiance[base].rgb, irradiance[base + 1u].rgb, f.x);
  vec3 b = mix(irradiance[base + rb].rgb, irradiance[base + rb + 1u].rgb, f.x);
  return mix(a, b, f.y);
}

vec2 sampleMoments(uint probe, vec3 d) {
  uint r = params.maps.y, rb = r + 2u;
  uvec2 t;
  vec2 f;
  octBilinear(d, r, t, f);
  uint base = probe * rb * rb + t.y * rb + t.x;
  vec2 a = mix(moments[base], moments[base + 1u], f.x);
  vec2 b = mix(moments[base + rb], moments[base + rb + 1u], f.x);
  return mix(a, b, f.y);
}

vec3 sampleSpecularLevel(uint probe, uint level, vec3 d) {
  uint r = params.maps.y, rb = r + 2u;
  uvec2 t;
  vec2 f;
  octBilinear(d, r, t, f);
  uint base = (probe * params.maps.z + level) * rb * rb + t.y * rb + t.x;
  vec3 a = mix(specular[base].rgb, specular[base + 1u].rgb, f.x);
  vec3 b = mix(specular[base + rb].rgb, specular[base + rb + 1u].rgb, f.x);
  return mix(a, b, f.y);
}

// Levels hold roughness k / (L - 1), k = 0..L-1; linear between the two nearest.
vec3 sampleSpecular(uint probe, vec3 d, float roughness) {
  uint levels = params.maps.z;
  if (levels <= 1u) return sampleSpecularLevel(probe, 0u, d);
  float x = clamp(roughness, 0.0, 1.0) * float(levels - 1u);
  uint l0 = min(uint(floor(x)), levels - 2u);
  return mix(sampleSpecularLevel(probe, l0, d), sampleSpecularLevel(probe, l0 + 1u, d), x - float(l0));
}

bool cellOwns(ShadeCell c, vec3 p) {
  vec3 hi = c.origin.xyz + vec3(c.dims.xyz) * c.spacing.xyz;
  return all(greaterThanEqual(p, c.origin.xyz)) && all(lessThan(p, hi));
}

bool fallbackOnly(ShadeCell c) {
  return c.spacing.w != 0.0;
}

// The cell owning p (half-open boxes), else the one whose box is nearest.
int cellFor(vec3 p) {
  int best = 0;
  float bestD = 1e30;
  for (uint i = 0u; i < params.size.z; ++i) {
    ShadeCell c = cells[i];
    if (cellOwns(c, p)) return int(i);
    vec3 hi = c.origin.xyz + vec3(c.dims.xyz) * c.spacing.xyz;
    vec3 q = clamp(p, c.origin.xyz, hi);
    float dd = dot(q - p, q - p);
    if (dd < bestD) {
      bestD = dd;
      best = int(i);
    }
  }
  return best;
}

// Lattice point `coord` (outside cell ci's grid) in another cell: a full cell whose lattice holds the same
// point in x and z gives its probe (>= 0); a fallback-only cell whose box holds the point (a quarter
// spacing further out, off the shared face) gives -1; none: -2. cellOut: that cell. Cells tile x and z
// and may place their layers at other heights (world cells do): a full neighbour's corner takes the
// neighbour's own layer below (offY 0) or above (offY 1) the point's height py, and wy its weight in the
// neighbour's y interpolation, so the neighbour's value at the face is its own trilinear value there, as
// StreamingManager::sample() evaluates it (-1: the caller's y weight holds).
int findCorner(int ci, ivec3 coord, float py, int offY, out int cellOut, out float wy) {
  ShadeCell c = cells[ci];
  vec3 q = c.origin.xyz + vec3(coord) * c.spacing.xyz;
  vec3 outward = vec3(greaterThanEqual(coord, c.dims.xyz)) - vec3(lessThan(coord, ivec3(0)));
  vec3 qOut = q + 0.25 * outward * c.spacing.xyz;
  int fb = -1;
  wy = -1.0;
  for (uint i = 0u; i < params.size.z; ++i) {
    if (int(i) == ci) continue;
    ShadeCell o = cells[i];
    if (fallbackOnly(o)) {
      if (fb < 0 && cellOwns(o, qOut)) fb = int(i);
      continue;
    }
    vec3 l = (q - o.origin.xyz) / o.spacing.xyz;
    ivec3 k = ivec3(round(l));
    if (k.x >= 0 && k.z >= 0 && k.x < o.dims.x && k.z < o.dims.z && abs(l.x - float(k.x)) < 1e-3 &&
        abs(l.z - float(k.z)) < 1e-3) {
      float ly = clamp((py - o.origin.y) / o.spacing.y, 0.0, float(o.dims.y - 1));
      int by = min(int(floor(ly)), max(o.dims.y - 2, 0));
      float ay = o.dims.y > 1 ? clamp(ly - float(by), 0.0, 1.0) : 0.0;
      k.y = min(by + offY, o.dims.y - 1);
      wy = offY != 0 ? ay : 1.0 - ay;
      cellOut = int(i);
      return o.dims.w + (k.z * o.dims.y + k.y) * o.dims.x + k.x;
    }
  }
  cellOut = fb;
  return fb >= 0 ? -1 : -2;
}

// Global probe index of lattice point `coord` of cell ci, or -1 where the point lies in a fallback-only
// cell (ci's own lattice points when ci is fallback-only: its box's grid); cellOut: the cell it belongs
// to. Inside ci's grid: its own probe; else another cell's (findCorner), first as is, then with y clamped into the grid (cells tile x and z: above or
// below the layers the neighbour's column counts, as StreamingManager::sample() clamps y); else the
// nearest probe of ci (clamping, as ProbeGrid::trilinear). used: the lattice point of ci taken (coord, or
// coord clamped on the axes with no cell beyond).
int latticeProbe(int ci, ivec3 coord, float py, int offY, out int cellOut, out ivec3 used, out float wy) {
  ShadeCell c = cells[ci];
  cellOut = ci;
  used = coord;
  wy = -1.0;
  if (all(greaterThanEqual(coord, ivec3(0))) && all(lessThan(coord, c.dims.xyz))) {
    return fallbackOnly(c) ? -1 : c.dims.w + (coord.z * c.dims.y + coord.y) * c.dims.x + coord.x;
  }
  int other;
  int found = findCorner(ci, coord, py, offY, other, wy);
  ivec3 yc = ivec3(coord.x, clamp(coord.y, 0, c.dims.y - 1), coord.z);
  if (found == -2 && yc != coord && (yc.x >= c.dims.x || yc.z >= c.dims.z || yc.x < 0 || yc.z < 0))
    found = findCorner(ci, yc, py, offY, other, wy);
  if (found != -2) {
    cellOut = other;
    return found;
  }
  if (fallbackOnly(c)) {
    // A fallback-only cell at the edge of the cells given: clamp one axis at a time, so a diagonal corner
    // takes the side neighbour's first layer (continuous with that neighbour's own clamped last layer).
    ivec3 lo = ivec3(0, 0, 0), hi = c.dims.xyz - ivec3(1);
    for (int axis = 0; axis < 2 && found == -2; ++axis) {
      ivec3 k = yc;
      if (axis == 0) k.x = clamp(k.x, lo.x, hi.x);
      else k.z = clamp(k.z, lo.z, hi.z);
      if (k != yc && (k.x >= c.dims.x || k.z >= c.dims.z || k.x < 0 || k.z < 0)) {
        found = findCorner(ci, k, py, offY, other, wy);
        used = k;
      }
    }
    if (found != -2) {
      cellOut = other;
      return found;
    }
    used = clamp(coord, ivec3(0), c.dims.xyz - ivec3(1));
    return -1;
  }
  ivec3 k = clamp(coord, ivec3(0), c.dims.xyz - ivec3(1));
  used = k;
  return c.dims.w + (k.z * c.dims.y + k.y) * c.dims.x + k.x;
}

// A fallback as irradiance coefficients: E(n) = e0 + ex n.x + ey n.y + ez n.z (rgb).
struct Fallback {
  vec3 e0, ex, ey, ez;
};

int fallbackCell(ShadeCell c, int dx, int dz) {
  int k = (dz + 1) * 3 + dx + 1;
  return c.fallbackCells[k / 4][k % 4];
}

// weight x the fallback at q: bilinear between the fallbacks of the 4 cell centres around q in xz
// (neighbours from cell ci's table), as StreamingManager::cellValue.
void addFallback(inout Fallback acc, int ci, vec3 q, float weight) {
  ShadeCell c = cells[ci];
  vec2 size = vec2(float(c.dims.x) * c.spacing.x, float(c.dims.z) * c.spacing.z);
  vec2 g = (q.xz - c.origin.xz) / size - vec2(0.5);
  ivec2 b = clamp(ivec2(floor(g)), ivec2(-1), ivec2(0));
  vec2 t = clamp(g - vec2(b), vec2(0.0), vec2(1.0));
  for (int k = 0; k < 4; ++k) {
    int dx = k & 1, dz = k >> 1;
    float w = weight * (dx != 0 ? t.x : 1.0 - t.x) * (dz != 0 ? t.y : 1.0 - t.y);
    if (w == 0.0) continue;
    ShadeCell f = cells[fallbackCell(c, b.x + dx, b.y + dz)];
    acc.e0 += w * f.fallback[0].rgb;
    acc.ex += w * f.fallback[1].rgb;
    acc.ey += w * f.fallback[2].rgb;
    acc.ez += w * f.fallback[3].rgb;
  }
}

vec3 fallbackIrradiance(Fallback f, vec3 n) {
  return max(f.e0 + f.ex * n.x + f.ey * n.y + f.ez * n.z, vec3(0.0));
}

// SH L1 radiance at r with its linear band scaled by 1 - alpha / 3 (mirror: the SH radiance; alpha 1:
// irradiance / pi, a cosine lobe).
vec3 fallbackRadiance(Fallback f, vec3 r, float roughness) {
  float alpha = clamp(roughness * roughness, 0.0, 1.0);
  float band1 = 1.5 - 0.5 * alpha;
  return max(f.e0 + band1 * (f.ex * r.x + f.ey * r.y + f.ez * r.z), vec3(0.0)) / kPi;
}

// Karis 2014, "Physically Based Shading on Mobile": analytic fit of the split-sum environment BRDF.
vec3 envBrdfApprox(vec3 f0, float roughness, float nv) {
  vec4 r = roughness * vec4(-1.0, -0.0275, -0.572, 0.022) + vec4(1.0, 0.0425, 1.04, -0.04);
  float a004 = min(r.x * r.x, exp2(-9.28 * nv)) * r.x + r.y;
  vec2 ab = vec2(-1.04, 1.04) * a004 + r.zw;
  return f0 * ab.x + ab.y;
}

bool isLambertian(float roughness, float metallic) {
  return metallic <= 0.0 && roughness >= 1.0;
}

vec3 diffuseBrdf(vec3 albedo, float roughness, float metallic) {
  return isLambertian(roughness, metallic) ? albedo / kPi : (1.0 - metallic) * (1.0 - 0.04) * albedo / kPi;
}

// bake/brdf.h: GGX D x height-correlated Smith V x Schlick F, alpha = max(roughness^2, 1e-3).
vec3 specularBrdf(vec3 albedo, float roughness, float metallic, vec3 n, vec3 v, vec3 l) {
  if (isLambertian(roughness, metallic)) return vec3(0.0);
  float nl = dot(n, l), nv = dot(n, v);
  if (nl <= 0.0 || nv <= 0.0) return vec3(0.0);
  vec3 h = normalize(v + l);
  float alpha = max(roughness * roughness, 1e-3);
  float a2 = alpha * alpha;
  float nh = max(dot(n, h), 0.0);
  float dd = nh * nh * (a2 - 1.0) + 1.0;
  float D = a2 / (kPi * dd * dd);
  float V = 0.5 / (nl * sqrt(nv * nv * (1.0 - a2) + a2) + nv * sqrt(nl * nl * (1.0 - a2) + a2));
  vec3 f0 = mix(vec3(0.04), albedo, metallic);
  vec3 F = f0 + (vec3(1.0) - f0) * pow(1.0 - max(dot(v, h), 0.0), 5.0);
  return D * V * F;
}

vec3 discLight(vec4 dir, vec4 irr, vec3 p, vec3 n, vec3 v, vec3 albedo, float rough, float metal) {
  float nl = dot(n, dir.xyz);
  if (nl <= 0.0 || max(irr.r, max(irr.g, irr.b)) <= 0.0) return vec3(0.0);
  if ((params.maps.w & 4u) != 0u) {
    float scale = max(max(abs(p.x), abs(p.y)), abs(p.z));
    vec3 o = p + n * (5e-4 + 4e-6 * scale);
    if (traceOccluded(o, dir.xyz, 0.0, params.bias.w)) return vec3(0.0);
  }
  vec3 f = diffuseBrdf(albedo, rough, metal) + specularBrdf(albedo, rough, metal, n, v, dir.xyz);
  return f * irr.rgb * nl;
}

// Ambient occlusion: the cosine-weighted fraction of the hemisphere with no geometry within radius,
// from LFGI_SHADE_AO_RAYS rays (Malley: stratified radii on the unit disc lifted to the hemisphere, golden-
// angle azimuths rotated per pixel by the R2 sequence so neighbouring pixels sample different directions).
float ambientOcclusion(vec3 p, vec3 n, uvec2 pix) {
  float radius = params.weights.w;
  vec3 t = normalize(abs(n.y) < 0.99 ? cross(n, vec3(0.0, 1.0, 0.0)) : cross(n, vec3(1.0, 0.0, 0.0)));
  vec3 b = cross(n, t);
  float scale = max(max(abs(p.x), abs(p.y)), abs(p.z));
  vec3 o = p + n * (5e-4 + 4e-6 * scale);
  float rot = fract(float(pix.x) * 0.7548776662 + float(pix.y) * 0.5698402910);
  float open = 0.0;
  for (uint k = 0u; k < LFGI_SHADE_AO_RAYS; ++k) {
    float u = (float(k) + 0.5) / float(LFGI_SHADE_AO_RAYS);
    float phi = 2.0 * kPi * fract(float(k) * 0.6180339887 + rot);
    float r = sqrt(u);
    vec3 d = t * (r * cos(phi)) + b * (r * sin(phi)) + n * sqrt(max(1.0 - u, 0.0));
    if (!traceOccluded(o, d, 0.0, radius)) open += 1.0;
  }
  return open / float(LFGI_SHADE_AO_RAYS);
}

void main() {
  uvec2 id = gl_GlobalInvocationID.xy;
  uvec2 size = params.size.xy;
  if (id.x >= size.x || id.y >= size.y) return;
  uint pixel = id.y * size.x + id.x;
  vec4 gp = gPosition[pixel];
  vec4 gn = gNormal[pixel];
  vec4 ga = gAlbedo[pixel];
  vec4 ge = gEmission[pixel];
  vec3 direct = vec3(0.0), diffuse = vec3(0.0), spec = vec3(0.0);
  float weightSum = 0.0;
  float fallbackShare = 0.0;
  float ao = 1.0;
  if (gp.w < 0.0) {
    vec3 d = normalize(gp.xyz);
    direct = skyRadiance(params.sky, d) + sunDiscRadiance(params.sky, d) + moonDiscRadiance(params.sky, d);
  } else if (ge.w == 0.0) {
    vec3 p = gp.xyz;
    vec3 n = normalize(gn.xyz);
    vec3 v = normalize(params.camera.position.xyz - p);
    float rough = gn.w, metal = ga.w;
    vec3 albedo = ga.rgb;
    direct = ge.rgb;
    direct += discLight(params.sky.sunDirection, params.sky.sunIrradiance, p, n, v, albedo, rough, metal);
    direct += discLight(params.sky.moonDirection, params.sky.moonIrradiance, p, n, v, albedo, rough, metal);

    // Majercik et al. 2019: look up from a point pushed along the normal and towards the viewer, so
    // the surface's own texels in the distance map do not shadow it.
    vec3 biased = p + n * params.bias.x + v * params.bias.y;
    int ci = cellFor(p);
    ShadeCell c = cells[ci];
    vec3 r = reflect(-v, n);
    bool wantSpec = !isLambertian(rough, metal) && params.weights.z != 0.0;
    vec3 irrSum = vec3(0.0), specSum = vec3(0.0);
    float beta = 0.0;  // the probes' share (the rest is fallback)
    Fallback fb = Fallback(vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0));
    // A fallback-only cell runs the same loop over its box's lattice with every own corner on the
    // fallback: in its last probe interval it blends into a resident neighbour's first layer, so the border
    // has no step from that side either (StreamingManager::sample() takes the fallback alone there).
    {
      vec3 local = (p - c.origin.xyz) / c.spacing.xyz;
      ivec3 base = clamp(ivec3(floor(local)), ivec3(0), c.dims.xyz - ivec3(1));
      vec3 alpha = clamp(local - vec3(base), vec3(0.0), vec3(1.0));
      float tSum = 0.0;
      vec4 column = vec4(0.0);  // fallback weight per corner column (off.x + 2 off.z)
      for (uint k = 0u; k < 8u; ++k) {
        ivec3 off = ivec3(int(k & 1u), int((k >> 1u) & 1u), int((k >> 2u) & 1u));
        int cellK;
        ivec3 used;
        float wy;
        int probe = latticeProbe(ci, base + off, p.y, off.y, cellK, used, wy);
        if (probe >= 0 && probes[probe].w == 0.0) continue;  // disabled probe (inside solid)
        vec3 tri = mix(vec3(1.0) - alpha, alpha, vec3(off));
        float trilinear = tri.x * (wy >= 0.0 ? wy : tri.y) * tri.z;
        tSum += trilinear;
        float fade = probe >= 0 ? cells[cellK].origin.w : 0.0;
        // A corner clamped at the edge of the cells given stands for the last layer on that axis: its
        // fallback too (as sample() at the world edge).
        column[clamp(used.x - base.x, 0, 1) + 2 * clamp(used.z - base.z, 0, 1)] += trilinear * (1.0 - fade);
        if (probe < 0 || fade <= 0.0) continue;
        beta += trilinear * fade;
        vec4 pr = probes[probe];
        float w = 1.0;
        if ((params.maps.w & 2u) != 0u) {
          vec3 toProbe = normalize(pr.xyz - p);
          float wrap = (dot(toProbe, n) + 1.0) * 0.5;
          w *= wrap * wrap + 0.2;
        }
        if ((params.maps.w & 1u) != 0u) {
          vec3 fromProbe = biased - pr.xyz;
          float dist = length(fromProbe);
          vec2 m = sampleMoments(uint(probe), fromProbe / max(dist, 1e-6));
          float cheb = 1.0;
          if (dist > m.x) {
            float variance = abs(m.y - m.x * m.x);
            float diff = dist - m.x;
            cheb = variance / (variance + diff * diff);
            cheb = cheb * cheb * cheb;
          }
          w *= max(cheb, params.bias.z);
        }
        w = max(w, 1e-6);
        if (w < 0.2) w *= w * w * (1.0 / (0.2 * 0.2));
        w *= trilinear * fade;
        irrSum += w * sampleIrradiance(uint(probe), n);
        if (wantSpec) specSum += w * sampleSpecular(uint(probe), r, rough);
        weightSum += w;
      }
      bool lastX = base.x + 1 == c.dims.x, lastZ = base.z + 1 == c.dims.z;
      if (!lastX) {  // both x columns evaluate at p.x: merge them
        column.xz += column.yw;
        column.yw = vec2(0.0);
      }
      if (!lastZ) {
        column.xy += column.zw;
        column.zw = vec2(0.0);
      }
      if (tSum > 0.0) {
        beta /= tSum;
        // Each column's fallback where StreamingManager::sample() evaluates it: on an x or z axis in the
        // grid's last probe interval, on the corner's lattice plane (last layer or face); else at p.
        for (int col = 0; col < 4; ++col) {
          if (column[col] <= 0.0) continue;
          vec3 q = p;
          if (lastX) q.x = c.origin.x + float(base.x + (col & 1)) * c.spacing.x;
          if (lastZ) q.z = c.origin.z + float(base.z + (col >> 1)) * c.spacing.z;
          addFallback(fb, ci, q, column[col] / tSum);
        }
      } else {
        addFallback(fb, ci, p, 1.0);  // every corner disabled
      }
    }
    fallbackShare = 1.0 - beta;
    if (params.weights.w > 0.0) ao = ambientOcclusion(p, n, id);
    vec3 irr = fallbackIrradiance(fb, n);
    if (weightSum > 0.0) irr += beta * irrSum / weightSum;
    diffuse = diffuseBrdf(albedo, rough, metal) * irr * ao;
    if (wantSpec) {
      vec3 rad = fallbackShare > 0.0 ? fallbackRadiance(fb, r, rough) : vec3(0.0);
      if (weightSum > 0.0) rad += beta * specSum / weightSum;
      vec3 f0 = mix(vec3(0.04), albedo, metal);
      spec = envBrdfApprox(f0, rough, max(dot(n, v), 1e-4)) * rad;
    }
  }
  direct *= params.weights.x;
  diffuse *= params.weights.y;
  outDirect[pixel] = vec4(direct, fallbackShare);
  outDiffuse[pixel] = vec4(diffuse, weightSum);
  outSpecular[pixel] = vec4(spec, ao);
  outTotal[pixel] = vec4(direct + diffuse + spec, 1.0);
}
