#include "bake/embree_scene.h"

#include <embree3/rtcore.h>

#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "core/error.h"

namespace lfgi::bake {
namespace {

const char* errorName(RTCError e) {
  switch (e) {
    case RTC_ERROR_NONE:
      return "no error";
    case RTC_ERROR_UNKNOWN:
      return "unknown error";
    case RTC_ERROR_INVALID_ARGUMENT:
      return "invalid argument";
    case RTC_ERROR_INVALID_OPERATION:
      return "invalid operation";
    case RTC_ERROR_OUT_OF_MEMORY:
      return "out of memory";
    case RTC_ERROR_UNSUPPORTED_CPU:
      return "unsupported CPU";
    case RTC_ERROR_CANCELLED:
      return "cancelled";
  }
  return "unrecognised error";
}

}  // namespace

struct EmbreeScene::Impl {
  worlds::TriangleMesh mesh;
  std::vector<glm::vec3> normals;
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  // Embree calls the error callback from inside C code, where an exception must not pass; the callback
  // records the message and check() throws it once control is back in C++.
  std::mutex errorMutex;
  std::string lastError;

  static void onError(void* user, RTCError code, const char* message) {
    auto* self = static_cast<Impl*>(user);
    std::lock_guard lock(self->errorMutex);
    self->lastError = std::string(errorName(code)) + ": " + (message ? message : "(no message)");
  }

  void check(const char* step) {
    const RTCError e = rtcGetDeviceError(device);
    if (e == RTC_ERROR_NONE) return;
    std::lock_guard lock(errorMutex);
    fail("Embree: {} failed: {}", step, lastError.empty() ? std::string(errorName(e)) : lastError);
  }

  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

EmbreeScene::EmbreeScene(worlds::TriangleMesh mesh, std::string_view what) : impl_(std::make_unique<Impl>()) {
  mesh.validate(what);
  Impl& s = *impl_;
  s.mesh = std::move(mesh);
  const size_t triangles = s.mesh.triangleCount();
  if (triangles > size_t(UINT32_MAX) || s.mesh.positions.size() > size_t(UINT32_MAX))
    fail("{}: {} triangles / {} vertices exceed Embree's 32-bit indices", what, triangles,
         s.mesh.positions.size());
  s.normals.resize(triangles);
  for (size_t t = 0; t < triangles; ++t) s.normals[t] = s.mesh.faceNormal(t);

  s.device = rtcNewDevice(nullptr);
  if (!s.device) fail("Embree: cannot create a device: {}", errorName(rtcGetDeviceError(nullptr)));
  rtcSetDeviceErrorFunction(s.device, &Impl::onError, &s);

  s.scene = rtcNewScene(s.device);
  s.check("rtcNewScene");
  rtcSetSceneFlags(s.scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(s.scene, RTC_BUILD_QUALITY_HIGH);
  if (triangles > 0) {
    RTCGeometry geom = rtcNewGeometry(s.device, RTC_GEOMETRY_TYPE_TRIANGLE);
    s.check("rtcNewGeometry");
    rtcSetGeometryBuildQuality(geom, RTC_BUILD_QUALITY_HIGH);
    // Embree may read 16 bytes at the last vertex; the shared buffers are owned by the scene (padded).
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), s.mesh.positions.size()));
    auto* idx = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
        geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), triangles));
    if (!v || !idx) {
      rtcReleaseGeometry(geom);
      s.check("rtcSetNewGeometryBuffer");
      fail("Embree: rtcSetNewGeometryBuffer returned no memory for {} ({} triangles)", what, triangles);
    }
    for (size_t i = 0; i < s.mesh.positions.size(); ++i) {
      v[i * 3 + 0] = s.mesh.positions[i].x;
      v[i * 3 + 1] = s.mesh.positions[i].y;
      v[i * 3 + 2] = s.mesh.positions[i].z;
    }
    std::copy(s.mesh.indices.begin(), s.mesh.indices.end(), idx);
    rtcCommitGeometry(geom);
    rtcAttachGeometryByID(s.scene, geom, 0);
    rtcReleaseGeometry(geom);
    s.check("building the triangle geometry");
  }
  rtcCommitScene(s.scene);
  s.check("rtcCommitScene");
}

EmbreeScene::~EmbreeScene() = default;
EmbreeScene::EmbreeScene(EmbreeScene&&) noexcept = default;
EmbreeScene& EmbreeScene::operator=(EmbreeScene&&) noexcept = default;

const worlds::TriangleMesh& EmbreeScene::mesh() const {
  return impl_->mesh;
}

const glm::vec3& EmbreeScene::faceNormal(uint32_t triangle) const {
  return impl_->normals[triangle];
}

std::optional<RayHit> EmbreeScene::intersect(glm::vec3 origin, glm::vec3 dir, float tNear, float tFar) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh{};
  rh.ray.org_x = origin.x;
  rh.ray.org_y = origin.y;
  rh.ray.org_z = origin.z;
  rh.ray.dir_x = dir.x;
  rh.ray.dir_y = dir.y;
  rh.ray.dir_z = dir.z;
  rh.ray.tnear = tNear;
  rh.ray.tfar = tFar;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &context, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  RayHit hit;
  hit.t = rh.ray.tfar;
  hit.triangle = rh.hit.primID;
  hit.normal = impl_->normals[hit.triangle];
  hit.barycentric = glm::vec2(rh.hit.u, rh.hit.v);
  hit.backface = glm::dot(dir, hit.normal) > 0.0f;
  return hit;
}

bool EmbreeScene::occluded(glm::vec3 origin, glm::vec3 dir, float tNear, float tFar) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay ray{};
  ray.org_x = origin.x;
  ray.org_y = origin.y;
  ray.org_z = origin.z;
  ray.dir_x = dir.x;
  ray.dir_y = dir.y;
  ray.dir_z = dir.z;
  ray.tnear = tNear;
  ray.tfar = tFar;
  ray.mask = 0xFFFFFFFFu;
  rtcOccluded1(impl_->scene, &context, &ray);
  // Embree marks an occluded ray by setting tfar to -inf.
  return ray.tfar < 0.0f;
}

}  // namespace lfgi::bake
