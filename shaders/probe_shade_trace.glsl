// BVH traversal over GpuBvhNode / GpuTriangle buffers, included by gbuffer_raycast.comp and probe_shade.comp.
// The including shader declares `nodes[]` and `tris[]` (std430 readonly buffers) before including this.
// Barrier-free, one ray per invocation, a fixed stack in registers (lavapipe: no shared memory).

const uint kTraceStackSize = 48u;

float traceBoxEntry(vec3 lo, vec3 hi, vec3 o, vec3 invDir, float tMax) {
  vec3 t0 = (lo - o) * invDir;
  vec3 t1 = (hi - o) * invDir;
  vec3 tn = min(t0, t1);
  vec3 tf = max(t0, t1);
  float enter = max(max(tn.x, tn.y), max(tn.z, 0.0));
  float leave = min(min(tf.x, tf.y), min(tf.z, tMax));
  return enter <= leave ? enter : 1e30;
}

// Closest hit with t in (tMin, tMax). Returns the hit triangle's index in tris[] (or -1), its t and
// barycentrics. Triangles are double-sided for hits (Moller & Trumbore 1997).
int traceClosest(vec3 o, vec3 d, float tMin, float tMax, out float tHit, out vec2 bary) {
  vec3 invDir = 1.0 / mix(d, vec3(1e-12), equal(d, vec3(0.0)));
  uint stack[kTraceStackSize];
  uint sp = 0u;
  uint node = 0u;
  int best = -1;
  tHit = tMax;
  bary = vec2(0.0);
  for (;;) {
    GpuBvhNode nd = nodes[node];
    uint count = floatBitsToUint(nd.hi.w);
    uint ref = floatBitsToUint(nd.lo.w);
    if (traceBoxEntry(nd.lo.xyz, nd.hi.xyz, o, invDir, tHit) < 1e29) {
      if (count > 0u) {
        for (uint k = ref; k < ref + count; ++k) {
          GpuTriangle tri = tris[k];
          vec3 p = cross(d, tri.e2.xyz);
          float det = dot(tri.e1.xyz, p);
          if (abs(det) < 1e-20) continue;
          float inv = 1.0 / det;
          vec3 s = o - tri.v0.xyz;
          float u = dot(s, p) * inv;
          if (u < 0.0 || u > 1.0) continue;
          vec3 q = cross(s, tri.e1.xyz);
          float v = dot(d, q) * inv;
          if (v < 0.0 || u + v > 1.0) continue;
          float t = dot(tri.e2.xyz, q) * inv;
          if (t > tMin && t < tHit) {
            tHit = t;
            best = int(k);
            bary = vec2(u, v);
          }
        }
      } else if (sp + 2u <= kTraceStackSize) {
        stack[sp++] = ref;       // right child
        node = node + 1u;        // left child next
        continue;
      }
    }
    if (sp == 0u) break;
    node = stack[--sp];
  }
  return best;
}

// True if anything lies on o + t d, t in (tMin, tMax).
bool traceOccluded(vec3 o, vec3 d, float tMin, float tMax) {
  vec3 invDir = 1.0 / mix(d, vec3(1e-12), equal(d, vec3(0.0)));
  uint stack[kTraceStackSize];
  uint sp = 0u;
  uint node = 0u;
  for (;;) {
    GpuBvhNode nd = nodes[node];
    uint count = floatBitsToUint(nd.hi.w);
    uint ref = floatBitsToUint(nd.lo.w);
    if (traceBoxEntry(nd.lo.xyz, nd.hi.xyz, o, invDir, tMax) < 1e29) {
      if (count > 0u) {
        for (uint k = ref; k < ref + count; ++k) {
          GpuTriangle tri = tris[k];
          vec3 p = cross(d, tri.e2.xyz);
          float det = dot(tri.e1.xyz, p);
          if (abs(det) < 1e-20) continue;
          float inv = 1.0 / det;
          vec3 s = o - tri.v0.xyz;
          float u = dot(s, p) * inv;
          if (u < 0.0 || u > 1.0) continue;
          vec3 q = cross(s, tri.e1.xyz);
          float v = dot(d, q) * inv;
          if (v < 0.0 || u + v > 1.0) continue;
          float t = dot(tri.e2.xyz, q) * inv;
          if (t > tMin && t < tMax) return true;
        }
      } else if (sp + 2u <= kTraceStackSize) {
        stack[sp++] = ref;
        node = node + 1u;
        continue;
      }
    }
    if (sp == 0u) break;
    node = stack[--sp];
  }
  return false;
}

// Camera ray through image-plane point (px, py) in pixels, as bake::cameraRayDirection.
vec3 cameraRay(GpuCamera c, uvec2 size, vec2 pixel) {
  float sx = (2.0 * pixel.x / float(size.x) - 1.0) * c.position.w * c.forward.w;
  float sy = (1.0 - 2.0 * pixel.y / float(size.y)) * c.position.w;
  return normalize(c.forward.xyz + sx * c.right.xyz + sy * c.up.xyz);
}
