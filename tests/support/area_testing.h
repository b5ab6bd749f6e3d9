// References for area lights, shared by area_light_test and bench_area: where to look (the
// surfaces under an emitter that a camera can see), and what is right there (the same VPLs
// with exact rays; the whole emitter by Monte Carlo).
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/eval/surface_sampling.h"
#include "cpvs/light/area_light.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/scene/scene.h"

namespace cpvs::testing {

/// Up to `count` points on surfaces facing the emitter's way back (their normal within 60
/// degrees of -normal) within `radius` of its centre across, outside every closed part (a
/// city's ground runs on inside its buildings); deterministic for a seed.
std::vector<SurfaceSample> pointsUnderArea(const Scene& scene, const RayScene& rays, const AreaLight& area, double radius,
                                           size_t count, uint64_t seed);

/// Whether point x is seen from surface point p (normal n) by an exact ray.
bool exactlySeenFrom(const RayScene& rays, const Vec3& x, const Vec3& p, const Vec3& n);

/// sum w_i seen_i / sum w_i over the lights (vplWeight, exact rays): what a bundle of
/// those VPLs answers without voxels.
double exactVplVisibility(const RayScene& rays, const std::vector<Light>& vpls, const Vec3& p, const Vec3& n);

/// The emitter itself: the same weighted fraction over m x m stratified points of the
/// rectangle (jittered by `seed`), exact rays.
double emitterVisibility(const RayScene& rays, const AreaLight& area, const Vec3& p, const Vec3& n, int m, uint64_t seed);

/// The mean and the 99th percentile of absolute errors.
double meanOf(const std::vector<double>& v);
double p99Of(std::vector<double> v);

}  // namespace cpvs::testing
