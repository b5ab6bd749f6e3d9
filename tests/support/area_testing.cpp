#include "area_testing.h"

#include <algorithm>
#include <cmath>

#include "cpvs/base/split_mix64.h"

namespace cpvs::testing {

std::vector<SurfaceSample> pointsUnderArea(const Scene& scene, const RayScene& rays, const AreaLight& area, double radius,
                                           size_t count, uint64_t seed) {
  const Vec3 n = area.normal(), u = normalize(area.edgeU), v = normalize(cross(n, u));
  std::vector<SurfaceSample> points;
  for (const SurfaceSample& s : sampleSurfaces(scene, rays, ClosedMode::Auto, n, 100 * count, seed)) {
    const Vec3 d = s.point - area.centre;
    if (-dot(s.normal, n) < 0.5 || std::abs(dot(d, u)) > radius || std::abs(dot(d, v)) > radius) continue;
    if (rays.closedNesting(s.point + s.normal * 1e-4, s.normal, 1e4, ClosedMode::Auto) > 0) continue;
    points.push_back(s);
    if (points.size() == count) break;
  }
  return points;
}

bool exactlySeenFrom(const RayScene& rays, const Vec3& x, const Vec3& p, const Vec3& n) {
  const Vec3 from = p + n * 1e-4;
  const Vec3 d = x - from;
  const double len = length(d);
  return !rays.occluded(from, d / len, 0.0, len);
}

double exactVplVisibility(const RayScene& rays, const std::vector<Light>& vpls, const Vec3& p, const Vec3& n) {
  double sum = 0, lit = 0;
  for (const Light& l : vpls) {
    const double w = vplWeight(l.position, l.direction, p, n);
    sum += w;
    if (w > 0 && exactlySeenFrom(rays, l.position, p, n)) lit += w;
  }
  return sum > 0 ? lit / sum : 0.0;
}

double emitterVisibility(const RayScene& rays, const AreaLight& area, const Vec3& p, const Vec3& n, int m, uint64_t seed) {
  SplitMix64 rng(seed);
  const Vec3 ne = area.normal();
  double sum = 0, lit = 0;
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) {
      const Vec3 x = area.centre + area.edgeU * ((i + rng.uniform01()) / m - 0.5) +
                     area.edgeV * ((j + rng.uniform01()) / m - 0.5);
      const double w = vplWeight(x, ne, p, n);
      sum += w;
      if (w > 0 && exactlySeenFrom(rays, x, p, n)) lit += w;
    }
  return sum > 0 ? lit / sum : 0.0;
}

double meanOf(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return v.empty() ? 0 : s / double(v.size());
}

double p99Of(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[size_t(0.99 * double(v.size() - 1))];
}

}  // namespace cpvs::testing
