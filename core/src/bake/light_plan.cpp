#include "cpvs/bake/light_plan.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "cpvs/base/error.h"
#include "cpvs/base/limits.h"
#include "cpvs/light/frustum_clip.h"
#include "cpvs/query/normal_offset.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

namespace {

constexpr double kDegrees = 3.14159265358979323846 / 180;

// A cube face's guard band, in texels beyond its 90-degree square: the widest filter's
// radius, the widest normal offset and one texel, so that a lookup of a point its face
// answers (cubeFace) never reads past the face's grid, whose texels there are dark.
constexpr double kFaceGuardTexels = kMaxPcfWidth / 2 + normalOffsetVoxels(kMaxPcfWidth) + 1;
// The smallest face grid whose guard band fits (a guard of g texels needs R > 2 g).
constexpr int kMinFaceLog2Resolution = 5;

// The view depth of the closest scene geometry inside the frustum of half-angle
// atan(tanHalf) along `frame` from `position`, not nearer than zMin > 0; infinity for none.
double closestDepth(const Scene& scene, const Vec3& position, const LightFrame& frame, double tanHalf, double zMin) {
  double closest = std::numeric_limits<double>::infinity();
  std::vector<LightPoint> poly, scratch;
  for (size_t t = 0; t < scene.triangleCount(); ++t) {
    poly.clear();
    for (int c = 0; c < 3; ++c) {
      const Vec3 q = scene.vertex(t, c) - position;
      poly.push_back({dot(q, frame.u), dot(q, frame.v), dot(q, frame.dir)});
    }
    clipToFrustum(poly, scratch, zMin, tanHalf);
    if (poly.size() < 3) continue;
    for (const LightPoint& p : poly) closest = std::min(closest, p.z);
  }
  return closest;
}

}  // namespace

std::vector<LightGridPlan> planLightGrids(const Scene& scene, const Light& light, double footprint) {
  if (scene.triangleCount() == 0) throw InputError("planning a light: the scene is empty");
  if (light.log2Resolution == 0 && !(footprint > 0 && std::isfinite(footprint)))
    throw InputError("planning a light: the texel footprint " + std::to_string(footprint) + " must be positive");
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  double far = light.range;
  if (far == 0) {
    for (int corner = 0; corner < 8; ++corner) {
      const Vec3 c{corner & 1 ? hi.x : lo.x, corner & 2 ? hi.y : lo.y, corner & 4 ? hi.z : lo.z};
      far = std::max(far, length(c - light.position));
    }
    far *= 1.0001;  // the farthest corner lies inside the grid
  }
  std::vector<std::pair<LightFrame, double>> views;  // frame and tan of the frustum's half-angle
  if (light.kind == LightKind::Spot) {
    views.push_back({LightFrame::fromDirection(light.direction), std::tan(light.coneDeg * kDegrees)});
  } else {
    for (int face = 0; face < 6; ++face) views.push_back({cubeFaceFrame(face, light.cube), 1.0});
  }
  std::vector<LightGridPlan> plans;
  for (const auto& [frame, tanHalf] : views) {
    // Geometry at the light itself (its fixture) counts too: near clamps it.
    const double closest = closestDepth(scene, light.position, frame, tanHalf, far * 1e-12);
    double near = light.near;
    if (near == 0) near = std::clamp(closest, far / kMaxDepthRatio, far / 2);
    int log2R = light.log2Resolution;
    if (log2R == 0) {
      const double texels = 2 * far * tanHalf / footprint;  // the frustum's width at far, in footprints
      log2R = std::clamp(int(std::ceil(std::log2(std::max(texels, 1.0)))), kMinLog2Resolution, kMaxPlannedLog2Resolution);
    }
    if (light.kind == LightKind::Spot) {
      plans.push_back({PerspectiveGrid(light.position, frame, tanHalf, near, far, log2R), tanHalf, closest});
      continue;
    }
    // A face: its square widened by the guard band, t = 1 + g (2 t / R); its cone (twice
    // the frustum's corner) cuts no texel.
    log2R = std::max(log2R, kMinFaceLog2Resolution);
    const double t = 1 / (1 - 2 * kFaceGuardTexels / double(uint64_t(1) << log2R));
    plans.push_back({PerspectiveGrid(light.position, frame, t, near, far, log2R), 2 * t, closest});
  }
  return plans;
}

}  // namespace cpvs
