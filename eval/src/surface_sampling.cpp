#include "cpvs/eval/surface_sampling.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "cpvs/base/error.h"
#include "cpvs/base/split_mix64.h"

namespace cpvs {

std::vector<SurfaceSample> sampleSurfaces(const Scene& scene, const RayScene& rays, ClosedMode closed,
                                          const Vec3& lightDir, uint64_t count, uint64_t seed) {
  size_t tris = scene.triangleCount();
  std::vector<double> cdf(tris + 1, 0.0);
  for (size_t t = 0; t < tris; ++t) {
    Vec3 a = scene.vertex(t, 0), b = scene.vertex(t, 1), c = scene.vertex(t, 2);
    cdf[t + 1] = cdf[t] + 0.5 * length(cross(b - a, c - a));
  }
  std::vector<SurfaceSample> out(count);
  if (tris == 0 || !(cdf[tris] > 0)) return {};
  tbb::parallel_for(uint64_t(0), count, [&](uint64_t i) {
    SplitMix64 rng = SplitMix64::forItem(seed, i);
    double pick = rng.uniform01() * cdf[tris];
    size_t t = size_t(std::upper_bound(cdf.begin(), cdf.end(), pick) - cdf.begin());
    t = std::clamp<size_t>(t, 1, tris) - 1;
    double r1 = rng.uniform01(), r2 = rng.uniform01();
    if (r1 + r2 > 1) {
      r1 = 1 - r1;
      r2 = 1 - r2;
    }
    Vec3 a = scene.vertex(t, 0), b = scene.vertex(t, 1), c = scene.vertex(t, 2);
    Vec3 n = normalize(cross(b - a, c - a));
    if (!rays.triangleClosed(uint32_t(t), closed) && dot(n, lightDir) > 0) n = -n;
    out[i] = SurfaceSample{a + (b - a) * r1 + (c - a) * r2, n};
  });
  return out;
}

std::vector<SurfaceSample> sampleCameraViews(const Scene& scene, const RayScene& rays,
                                             const std::vector<Camera>& cameras, double aspect, uint64_t count,
                                             uint64_t seed) {
  if (cameras.empty()) throw InputError("camera sampling needs at least one camera");
  if (!(aspect > 0) || !std::isfinite(aspect)) throw InputError("camera sampling: aspect must be positive");
  std::vector<CameraRays> views;
  for (const Camera& c : cameras) views.emplace_back(c, aspect);
  std::vector<SurfaceHit> hits(count);
  tbb::parallel_for(uint64_t(0), count, [&](uint64_t i) {
    const CameraRays& view = views[i % views.size()];
    SplitMix64 rng = SplitMix64::forItem(seed, i);
    for (int attempt = 0; attempt < kCameraSampleAttempts; ++attempt) {
      const double ix = rng.uniform01(), iy = rng.uniform01();
      if (firstSurface(scene, rays, view.eye(), view.through(ix, iy), hits[i])) break;
    }
  });
  std::vector<SurfaceSample> out;
  out.reserve(count);
  for (const SurfaceHit& h : hits)
    if (h.hit) out.push_back({h.point, h.normal});
  return out;
}

}  // namespace cpvs
