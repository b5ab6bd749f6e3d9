#include "cpvs/ray_scene.h"

#include <embree3/rtcore.h>

#include <cmath>
#include <limits>
#include <string>

#include "cpvs/scene.h"

namespace cpvs {

namespace {

void embreeError(void*, RTCError code, const char* message) {
  // Embree reports misuse and allocation failures here; both are bugs or fatal, and the
  // caller sees the failed call through rtcGetDeviceError as well.
  if (code != RTC_ERROR_NONE) throw std::runtime_error(std::string("embree: ") + message);
}

}  // namespace

RayScene::RayScene(const Scene& scene, const Vec3& origin, int threads) : origin_(origin) {
  std::string config = threads > 0 ? "threads=" + std::to_string(threads) : std::string();
  RTCDevice device = rtcNewDevice(config.empty() ? nullptr : config.c_str());
  if (!device) throw std::runtime_error("embree: cannot create a device");
  rtcSetDeviceErrorFunction(device, embreeError, nullptr);
  device_ = device;

  RTCScene rs = rtcNewScene(device);
  rtcSetSceneFlags(rs, RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
  rtcSetSceneBuildQuality(rs, RTC_BUILD_QUALITY_HIGH);
  scene_ = rs;

  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* verts = static_cast<float*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), scene.positions.size()));
  for (size_t i = 0; i < scene.positions.size(); ++i) {
    // Subtract in double, then round once: the float keeps the local detail.
    Vec3 p = scene.positions[i] - origin;
    verts[3 * i + 0] = static_cast<float>(p.x);
    verts[3 * i + 1] = static_cast<float>(p.y);
    verts[3 * i + 2] = static_cast<float>(p.z);
  }
  size_t tris = scene.triangleCount();
  auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), tris));
  for (size_t i = 0; i < 3 * tris; ++i) idx[i] = scene.indices[i];
  rtcCommitGeometry(geom);
  rtcAttachGeometryByID(rs, geom, 0);
  rtcReleaseGeometry(geom);
  rtcCommitScene(rs);

  closed_.assign(tris, 0);
  for (size_t i = 0; i < tris && i < scene.closed.size(); ++i) closed_[i] = scene.closed[i];
}

RayScene::~RayScene() {
  if (scene_) rtcReleaseScene(static_cast<RTCScene>(scene_));
  if (device_) rtcReleaseDevice(static_cast<RTCDevice>(device_));
}

namespace {

RTCRayHit makeRay(const Vec3& localFrom, const Vec3& dir, double tnear, double tfar) {
  RTCRayHit r{};
  r.ray.org_x = static_cast<float>(localFrom.x);
  r.ray.org_y = static_cast<float>(localFrom.y);
  r.ray.org_z = static_cast<float>(localFrom.z);
  r.ray.dir_x = static_cast<float>(dir.x);
  r.ray.dir_y = static_cast<float>(dir.y);
  r.ray.dir_z = static_cast<float>(dir.z);
  r.ray.tnear = static_cast<float>(tnear);
  r.ray.tfar = tfar >= double(std::numeric_limits<float>::max()) ? std::numeric_limits<float>::infinity()
                                                                  : static_cast<float>(tfar);
  r.ray.mask = 0xFFFFFFFFu;
  r.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  return r;
}

}  // namespace

bool RayScene::occluded(const Vec3& from, const Vec3& dir, double tnear, double tfar) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh = makeRay(from - origin_, dir, tnear, tfar);
  rtcOccluded1(static_cast<RTCScene>(scene_), &ctx, &rh.ray);
  return rh.ray.tfar < 0.0f;  // Embree sets tfar = -inf on occlusion
}

bool RayScene::intersect(const Vec3& from, const Vec3& dir, double tnear, double tfar,
                         RayHit& hit) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh = makeRay(from - origin_, dir, tnear, tfar);
  rtcIntersect1(static_cast<RTCScene>(scene_), &ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
  hit.t = rh.ray.tfar;
  hit.triangle = rh.hit.primID;
  hit.front = (rh.hit.Ng_x * rh.ray.dir_x + rh.hit.Ng_y * rh.ray.dir_y + rh.hit.Ng_z * rh.ray.dir_z) < 0;
  hit.closed = closed_[hit.triangle] != 0;
  return true;
}

}  // namespace cpvs
