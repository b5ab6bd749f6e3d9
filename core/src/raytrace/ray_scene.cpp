#include "cpvs/raytrace/ray_scene.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "cpvs/scene/scene.h"

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

  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  tieDistance_ = 1e-6 * length(hi - lo);
  closed_.assign(tris, 0);
  for (size_t i = 0; i < tris && i < scene.closed.size(); ++i) closed_[i] = scene.closed[i];
}

bool RayScene::anyClosed(ClosedMode mode) const {
  if (mode != ClosedMode::Auto) return mode == ClosedMode::On && !closed_.empty();
  return std::find(closed_.begin(), closed_.end(), uint8_t(1)) != closed_.end();
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

namespace {

struct NestingContext {
  RTCIntersectContext ctx;
  const RayScene* rays;
  ClosedMode mode;
  std::vector<std::pair<float, int>>* crossings;  // (t, +1 leaving / -1 entering)
};

void nestingFilter(const RTCFilterFunctionNArguments* args) {
  auto* c = reinterpret_cast<const NestingContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    args->valid[i] = 0;  // reject every hit so that traversal visits them all
    unsigned prim = RTCHitN_primID(args->hit, args->N, i);
    if (!c->rays->triangleClosed(prim, c->mode)) continue;
    float ng = RTCHitN_Ng_x(args->hit, args->N, i) * RTCRayN_dir_x(args->ray, args->N, i) +
               RTCHitN_Ng_y(args->hit, args->N, i) * RTCRayN_dir_y(args->ray, args->N, i) +
               RTCHitN_Ng_z(args->hit, args->N, i) * RTCRayN_dir_z(args->ray, args->N, i);
    c->crossings->emplace_back(RTCRayN_tfar(args->ray, args->N, i), ng > 0 ? 1 : -1);
  }
}

}  // namespace

int RayScene::closedNesting(const Vec3& from, const Vec3& dir, double tfar, ClosedMode mode) const {
  std::vector<std::pair<float, int>> crossings;
  NestingContext c{{}, this, mode, &crossings};
  rtcInitIntersectContext(&c.ctx);
  c.ctx.filter = nestingFilter;
  RTCRayHit rh = makeRay(from - origin_, dir, 0.0, tfar);
  rtcIntersect1(static_cast<RTCScene>(scene_), &c.ctx, &rh);
  // A ray through a shared edge or vertex may report each triangle around it: crossings
  // of the same sign at (almost) the same distance are one crossing.
  std::sort(crossings.begin(), crossings.end());
  const float eps = float(tieDistance_);
  int nesting = 0;
  for (size_t i = 0; i < crossings.size(); ++i) {
    bool duplicate = false;
    for (size_t j = i; j-- > 0 && crossings[i].first - crossings[j].first <= eps;)
      if (crossings[j].second == crossings[i].second) duplicate = true;
    if (!duplicate) nesting += crossings[i].second;
  }
  return nesting;
}

}  // namespace cpvs
