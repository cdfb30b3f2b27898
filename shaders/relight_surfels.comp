#version 450
// Relight: irradiance E at every surfel for this frame, one invocation per surfel, no barriers.
//   E = key disc (sun, or moon at night) x max(0, n.L) x shadow-map visibility
//     + last frame's probe irradiance at (p, n): trilinear over the 8 surrounding probes of the grid with
//       DDGI weights (Majercik et al. 2019, "Dynamic Diffuse Global Illumination with Ray-Traced
//       Irradiance Fields": smooth backface term, Chebyshev visibility from the probes' distance moments
//       as in McGuire et al. 2017, weight crushing below 0.2; faded to 0 where nearly every probe is
//       occluded, see probeLighting); the Chebyshev bound is taken per bilinear tap, then filtered
//       (visibility()). The probe maps hold the sky (seen through
//       the probe's own occlusion) and every bounce up to the last frame, so multi-bounce converges over
//       frames and the sky is occluded as the probes see it.
// Shadow test: single tap of the texel containing the surfel centre; lit iff
//   depth(surfel) <= stored depth + bias, bias = biasConstant + biasSlope x texel x min(tan(theta), 10),
// theta the angle between the normal and the light (a plane's depth changes by texel x tan(theta) across
// one texel). Points outside the map or on empty texels are lit.
// Emitter next-event estimation (LFGI_RELIGHT_EMITTERS): direct light from emissive surfels (a lamp, lit
// windows) as a sum over emitter samples, each a disc of area A and radiance L:
//   E += L A cos(receiver) cos(emitter) / (d^2 + A / pi)  x  visibility(cluster)
// (the A / pi term makes one sample exact on the axis of a disc, pi L R^2 / (R^2 + d^2), and keeps the near
// field finite). Visibility: one octahedral depth map per emitter cluster, VIR-splatted from the cluster's
// centre (gpu/relight_pass.h); 2 x 2 taps, each lit iff the receiver's distance <= stored + bias. With
// emitters on, the probe gather reads probe maps *without* emission (relightFrame keeps both), so the
// emitters' direct light is counted once, here, and not again through the probes.
// Output: rgb = E, w = key visibility (0 or 1; 0 when the surfel faces away from the light).
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "shared/octahedral.h"
#include "shared/relight.h"
#include "shared/surfel.h"

layout(local_size_x = 64, local_size_y = 1, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Surfels { Surfel surfels[]; };
layout(std430, set = 0, binding = 1) readonly buffer Frame { RelightFrame frame; };
layout(std430, set = 0, binding = 2) readonly buffer Slots { uint64_t slots[]; };
layout(std430, set = 0, binding = 3) readonly buffer ProbePositions { vec4 probePositions[]; };
layout(std430, set = 0, binding = 4) readonly buffer ProbeIrradiance { vec4 probeIrradiance[]; };
layout(std430, set = 0, binding = 5) readonly buffer ProbeMoments { vec2 probeMoments[]; };
layout(std430, set = 0, binding = 6) writeonly buffer Irradiance { vec4 irradiance[]; };
layout(std430, set = 0, binding = 7) readonly buffer Emitters { RelightEmitter emitters[]; };
layout(std430, set = 0, binding = 8) readonly buffer EmitterCentres { vec4 emitterCentres[]; };
layout(std430, set = 0, binding = 9) readonly buffer EmitterShadow { float emitterShadow[]; };

layout(push_constant) uniform Push { RelightParams params; };

// Bilinear taps of an n x n octahedral map at direction d: texel indices (within the map) and weights.
void octBilinear(vec3 d, int n, out ivec2 t[4], out vec4 w) {
  vec2 f = (octEncode(d) * 0.5 + vec2(0.5)) * float(n) - vec2(0.5);
  vec2 b = floor(f);
  vec2 a = f - b;
  ivec2 i0 = ivec2(b);
  t[0] = octWrap(i0, n);
  t[1] = octWrap(i0 + ivec2(1, 0), n);
  t[2] = octWrap(i0 + ivec2(0, 1), n);
  t[3] = octWrap(i0 + ivec2(1, 1), n);
  w = vec4((1.0 - a.x) * (1.0 - a.y), a.x * (1.0 - a.y), (1.0 - a.x) * a.y, a.x * a.y);
}

vec3 sampleIrradiance(uint probe, vec3 d) {
  int m = int(params.irradianceRes);
  ivec2 t[4];
  vec4 w;
  octBilinear(d, m, t, w);
  uint base = probe * uint(m * m);
  return probeIrradiance[base + uint(t[0].y * m + t[0].x)].rgb * w.x +
         probeIrradiance[base + uint(t[1].y * m + t[1].x)].rgb * w.y +
         probeIrradiance[base + uint(t[2].y * m + t[2].x)].rgb * w.z +
         probeIrradiance[base + uint(t[3].y * m + t[3].x)].rgb * w.w;
}

float chebyshev(vec2 m, float r) {
  if (r <= m.x) return 1.0;
  float variance = max(abs(m.y - m.x * m.x), 1e-4 * m.x * m.x);
  float dr = r - m.x;
  return variance / (variance + dr * dr);
}

// Chebyshev visibility of the point at distance r along d from a probe: the bound per bilinear tap, then
// filtered (as percentage-closer filtering filters depth tests). Filtering the moments first would mix a
// sky tap's (miss, miss^2) into its neighbours: a mean of miss / 4 and a huge variance, so a probe above a
// roof saw every point below its sky-bordered texels (lfgi_bench_stability leak).
float visibility(uint probe, vec3 d, float r) {
  int n = int(params.distanceRes);
  ivec2 t[4];
  vec4 w;
  octBilinear(d, n, t, w);
  uint base = probe * uint(n * n);
  return chebyshev(probeMoments[base + uint(t[0].y * n + t[0].x)], r) * w.x +
         chebyshev(probeMoments[base + uint(t[1].y * n + t[1].x)], r) * w.y +
         chebyshev(probeMoments[base + uint(t[2].y * n + t[2].x)], r) * w.z +
         chebyshev(probeMoments[base + uint(t[3].y * n + t[3].x)], r) * w.w;
}

vec3 probeLighting(vec3 p, vec3 n) {
  ivec3 dims = frame.gridDims.xyz;
  vec3 g = (p - frame.gridOrigin.xyz) / frame.gridSpacing.xyz;
  vec3 gc = clamp(g, vec3(0.0), vec3(dims - ivec3(1)));
  ivec3 base = min(ivec3(floor(gc)), max(dims - ivec3(2), ivec3(0)));
  vec3 f = clamp(gc - vec3(base), vec3(0.0), vec3(1.0));
  float normalBias = frame.gridSpacing.w;
  vec3 sum = vec3(0.0);
  float wsum = 0.0;
  float wsumOpen = 0.0;  // the same weights without the Chebyshev factor
  for (int i = 0; i < 8; ++i) {
    ivec3 off = ivec3(i & 1, (i >> 1) & 1, (i >> 2) & 1);
    ivec3 c = min(base + off, dims - ivec3(1));
    vec3 tri = mix(vec3(1.0) - f, f, vec3(off));
    float trilinear = tri.x * tri.y * tri.z;
    if (trilinear <= 0.0) continue;
    uint idx = uint((c.z * dims.y + c.y) * dims.x + c.x);
    vec4 pp = probePositions[idx];
    if (pp.w == 0.0) continue;  // disabled probe (inside solid geometry)
    vec3 toProbe = pp.xyz - p;
    float dist = length(toProbe);
    float w = 1.0;
    if (dist > 1e-6) {
      float back = (dot(toProbe / dist, n) + 1.0) * 0.5;
      w = back * back + 0.2;
    }
    wsumOpen += w * trilinear;
    if ((params.flags & LFGI_RELIGHT_CHEBYSHEV) != 0u) {
      vec3 q = p + n * normalBias - pp.xyz;
      float r = length(q);
      if (r > 1e-6) {
        float cheb = visibility(idx, q / r, r);
        w *= cheb * cheb * cheb;
      }
    }
    w = max(w, 1e-6);
    if (w < 0.2) w *= w * w / (0.2 * 0.2);
    w *= trilinear;
    sum += w * sampleIrradiance(idx, n);
    wsum += w;
  }
  // DDGI renormalises by the weight sum, so a point that every probe sees as occluded (the underside of
  // a floor, the inside of a solid) still gets the full irradiance: a leak. Fade the result out once the
  // visible weight falls below kVisibleFloor of what it would be with every probe visible.
  const float kVisibleFloor = 0.2;
  if (wsum <= 0.0) return vec3(0.0);
  return sum / wsum * min(1.0, wsum / (kVisibleFloor * wsumOpen));
}

float emitterVisibility(uint cluster, vec3 p, vec3 n) {
  vec3 v = p + n * frame.emitterBias.x - emitterCentres[cluster].xyz;
  float r = length(v);
  if (r < 1e-6) return 1.0;
  int res = int(frame.emitters.z);
  ivec2 t[4];
  vec4 w;
  octBilinear(v / r, res, t, w);
  uint base = cluster * uint(res * res);
  float bias = frame.emitterBias.y + frame.emitterBias.z * r;
  vec4 lit = vec4(r <= emitterShadow[base + uint(t[0].y * res + t[0].x)] + bias ? 1.0 : 0.0,
                  r <= emitterShadow[base + uint(t[1].y * res + t[1].x)] + bias ? 1.0 : 0.0,
                  r <= emitterShadow[base + uint(t[2].y * res + t[2].x)] + bias ? 1.0 : 0.0,
                  r <= emitterShadow[base + uint(t[3].y * res + t[3].x)] + bias ? 1.0 : 0.0);
  return dot(lit, w);
}

// Samples are sorted by cluster, so the visibility lookup runs once per cluster that can light p.
vec3 emitterLight(vec3 p, vec3 n) {
  const float kPi = 3.14159265358979;
  vec3 e = vec3(0.0);
  uint lastCluster = 0xFFFFFFFFu;
  float vis = 0.0;
  for (uint j = 0u; j < frame.emitters.x; ++j) {
    vec3 d = emitters[j].positionArea.xyz - p;
    float d2 = dot(d, d);
    float inv = inversesqrt(max(d2, 1e-20));
    float cr = dot(n, d) * inv;
    float ce = -dot(emitters[j].normalCluster.xyz, d) * inv;
    if (cr <= 0.0 || ce <= 0.0) continue;
    uint cluster = floatBitsToUint(emitters[j].normalCluster.w);
    if (cluster != lastCluster) {
      vis = emitterVisibility(cluster, p, n);
      lastCluster = cluster;
    }
    if (vis <= 0.0) continue;
    float area = emitters[j].positionArea.w;
    e += emitters[j].radiance.rgb * (area * cr * ce / (d2 + area / kPi) * vis);
  }
  return e;
}

void main() {
  uint s = gl_GlobalInvocationID.x;
  if (s >= params.surfelCount) return;
  vec3 p = surfels[s].positionRadius.xyz;
  vec3 n = surfels[s].normal.xyz;
  vec3 e = vec3(0.0);
  float visible = 0.0;
  vec3 L = frame.keyDirection.xyz;
  float nl = dot(n, L);
  if ((params.flags & LFGI_RELIGHT_SUN) != 0u && frame.keyDirection.w != 0.0 && nl > 0.0) {
    visible = 1.0;
    float ts = frame.shadowDepth.y;
    int res = int(params.shadowRes);
    ivec2 t = ivec2(floor((dot(p, frame.shadowAxisU.xyz) - frame.shadowAxisU.w) / ts),
                    floor((dot(p, frame.shadowAxisV.xyz) - frame.shadowAxisV.w) / ts));
    if (t.x >= 0 && t.y >= 0 && t.x < res && t.y < res) {
      uint64_t v = slots[uint(t.y) * params.shadowRes + uint(t.x)];
      if (v != 0xFFFFFFFFFFFFFFFFUL) {
        float stored = uintBitsToFloat(uint(v >> 32));
        float depth = frame.shadowDepth.x - dot(p, L);
        float tanTheta = min(sqrt(max(1.0 - nl * nl, 0.0)) / nl, 10.0);
        float bias = frame.shadowDepth.z + frame.shadowDepth.w * ts * tanTheta;
        visible = depth <= stored + bias ? 1.0 : 0.0;
      }
    }
    e += frame.keyIrradiance.rgb * (nl * visible);
  }
  if ((params.flags & LFGI_RELIGHT_EMITTERS) != 0u) e += emitterLight(p, n);
  if ((params.flags & LFGI_RELIGHT_BOUNCE) != 0u && params.probeCount > 0u) e += probeLighting(p, n);
  irradiance[s] = vec4(e, visible);
}
