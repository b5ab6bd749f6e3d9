#include "cpvs/eval/surface_sampling.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "cpvs/base/error.h"
#include "cpvs/base/split_mix64.h"

namespace cpvs {

namespace {

// Triangles picked with probability proportional to their area, among those `take`
// accepts, and uniform points on them.
class AreaPicker {
 public:
  template <class Take>
  AreaPicker(const Scene& scene, Take&& take) : scene_(scene), cdf_(scene.triangleCount() + 1, 0.0) {
    for (size_t t = 0; t < scene.triangleCount(); ++t)
      cdf_[t + 1] = cdf_[t] + (take(uint32_t(t)) ? triangleArea(scene, t) : 0.0);
  }

  bool empty() const { return !(cdf_.back() > 0); }

  // A triangle and a uniform point on it, from three draws of rng.
  std::pair<size_t, Vec3> pick(SplitMix64& rng) const {
    const size_t tris = scene_.triangleCount();
    size_t t = size_t(std::upper_bound(cdf_.begin(), cdf_.end(), rng.uniform01() * cdf_[tris]) - cdf_.begin());
    t = std::clamp<size_t>(t, 1, tris) - 1;
    double r1 = rng.uniform01(), r2 = rng.uniform01();
    if (r1 + r2 > 1) r1 = 1 - r1, r2 = 1 - r2;
    const Vec3 a = scene_.vertex(t, 0), b = scene_.vertex(t, 1), c = scene_.vertex(t, 2);
    return {t, a + (b - a) * r1 + (c - a) * r2};
  }

 private:
  const Scene& scene_;
  std::vector<double> cdf_;
};

// `count` points uniform by area over the triangles `take` accepts, each with the normal
// of the side `side(t, rng)` picks (+1 front, -1 back).
template <class Take, class Side>
std::vector<SurfaceSample> sampleByArea(const Scene& scene, uint64_t count, uint64_t seed, Take&& take, Side&& side) {
  const AreaPicker picker(scene, take);
  if (picker.empty()) return {};
  std::vector<SurfaceSample> out(count);
  tbb::parallel_for(uint64_t(0), count, [&](uint64_t i) {
    SplitMix64 rng = SplitMix64::forItem(seed, i);
    const auto [t, p] = picker.pick(rng);
    const Vec3 a = scene.vertex(t, 0), b = scene.vertex(t, 1), c = scene.vertex(t, 2);
    out[i] = SurfaceSample{p, normalize(cross(b - a, c - a)) * side(uint32_t(t), rng)};
  });
  return out;
}

// Whether p lies inside the closed mesh: the parity of a ray's crossings, along a
// direction no axis-aligned box face is parallel to.
bool insideClosedMesh(const Scene& mesh, const Vec3& p) {
  const Vec3 d = normalize(Vec3{0.5773, 0.5801, 0.5746});
  int crossings = 0;
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    const Vec3 a = mesh.vertex(t, 0), e1 = mesh.vertex(t, 1) - a, e2 = mesh.vertex(t, 2) - a;
    const Vec3 h = cross(d, e2);
    const double det = dot(e1, h);
    if (std::fabs(det) < 1e-300) continue;
    const Vec3 s = p - a;
    const double u = dot(s, h) / det;
    if (u < 0 || u > 1) continue;
    const Vec3 q = cross(s, e1);
    const double v = dot(d, q) / det;
    if (v < 0 || u + v > 1) continue;
    if (dot(e2, q) / det > 0) ++crossings;
  }
  return crossings % 2 == 1;
}

}  // namespace

std::vector<SurfaceSample> sampleSurfaces(const Scene& scene, const RayScene& rays, ClosedMode closed,
                                          const Vec3& lightDir, uint64_t count, uint64_t seed) {
  return sampleByArea(scene, count, seed, [](uint32_t) { return true; },
                      [&](uint32_t t, SplitMix64&) {
                        const Vec3 a = scene.vertex(t, 0), b = scene.vertex(t, 1), c = scene.vertex(t, 2);
                        return !rays.triangleClosed(t, closed) && dot(cross(b - a, c - a), lightDir) > 0 ? -1.0 : 1.0;
                      });
}

std::vector<SurfaceSample> sampleSpotSurfaces(const Scene& scene, const RayScene& rays, ClosedMode closed,
                                              const PerspectiveGrid& grid, double tanCone, uint64_t count,
                                              uint64_t seed, const std::vector<uint8_t>* sides) {
  const Vec3 lamp = grid.position(), axis = grid.frame().dir;
  const double cone = std::atan(tanCone);
  // A triangle may reach into the cone when its bounding sphere does: the sphere holds the
  // light, or its angle from the axis, less the angle the sphere subtends, is within it.
  const AreaPicker picker(scene, [&](uint32_t t) {
    if (sides && (*sides)[t] == 0) return false;
    const Vec3 a = scene.vertex(t, 0), b = scene.vertex(t, 1), c = scene.vertex(t, 2);
    const Vec3 centre = (a + b + c) / 3.0;
    const double r = std::max({length(a - centre), length(b - centre), length(c - centre)});
    const Vec3 q = centre - lamp;
    const double d = length(q);
    if (d <= r) return true;
    const double angle = std::acos(std::clamp(dot(q, axis) / d, -1.0, 1.0));
    return angle - std::asin(r / d) <= cone;
  });
  if (picker.empty()) return {};
  std::vector<SurfaceSample> drawn(count);
  std::vector<uint8_t> found(count, 0);
  tbb::parallel_for(uint64_t(0), count, [&](uint64_t i) {
    SplitMix64 rng = SplitMix64::forItem(seed, i);
    for (int attempt = 0; attempt < kConeSampleAttempts; ++attempt) {
      const auto [t, p] = picker.pick(rng);
      if (!grid.insideCone(p, tanCone)) continue;
      const Vec3 a = scene.vertex(t, 0), b = scene.vertex(t, 1), c = scene.vertex(t, 2);
      Vec3 n = normalize(cross(b - a, c - a));
      const bool open = !rays.triangleClosed(uint32_t(t), closed);
      uint8_t side = 1;
      if (open && dot(n, lamp - p) < 0) n = -n, side = 2;
      if (sides && !((*sides)[t] & side)) {
        // The side facing the light does not receive: the other one, where it does.
        if (!open || !((*sides)[t] & (3 - side))) continue;
        n = -n;
      }
      drawn[i] = SurfaceSample{p, n};
      found[i] = 1;
      return;
    }
  });
  std::vector<SurfaceSample> out;
  for (uint64_t i = 0; i < count; ++i)
    if (found[i]) out.push_back(drawn[i]);
  return out;
}

std::vector<SurfaceSample> sampleReceivers(const Scene& scene, const RayScene& rays, ClosedMode closed,
                                           const Vec3& lightDir, const ReceiverDeclaration& d, uint64_t count,
                                           uint64_t seed) {
  if (d.kind == ReceiverKind::Everywhere) return sampleSurfaces(scene, rays, closed, lightDir, count, seed);
  // By area over the triangles that receive, on a side that receives (receivingSides).
  const std::vector<uint8_t> sides = receivingSides(scene, d);
  const bool mesh = d.volume.triangleCount() != 0, layer = d.groundLayer > 0;
  const uint64_t inVolume = mesh || layer ? count / 2 : 0;
  std::vector<SurfaceSample> out = sampleByArea(
      scene, count - inVolume, seed,
      [&](uint32_t t) { return sides[t] != 0; },
      [&](uint32_t t, SplitMix64& rng) { return sides[t] == 2 || (sides[t] == 3 && rng.uniform01() < 0.5) ? -1.0 : 1.0; });
  if (inVolume == 0) return out;
  // Points of the ground layer: on a walkable triangle (by area), raised within the layer.
  const AreaPicker walkableArea(scene, [&](uint32_t t) { return walkable(scene, d, t); });
  const bool layerSampled = !walkableArea.empty();
  if (!mesh && !layerSampled) return out;
  Vec3 lo, hi;
  if (mesh) sceneBounds(d.volume, lo, hi);
  std::vector<SurfaceSample> inside(inVolume);
  tbb::parallel_for(uint64_t(0), inVolume, [&](uint64_t i) {
    SplitMix64 rng = SplitMix64::forItem(seed ^ 0x766f6c756d65ull, i);
    Vec3 p;
    if (layerSampled && (!mesh || i % 2 == 1)) {
      p = walkableArea.pick(rng).second;
      p.y += d.groundLayerFrom + (d.groundLayer - d.groundLayerFrom) * rng.uniform01();
    } else {
      do {
        p = {lo.x + (hi.x - lo.x) * rng.uniform01(), lo.y + (hi.y - lo.y) * rng.uniform01(),
             lo.z + (hi.z - lo.z) * rng.uniform01()};
      } while (!insideClosedMesh(d.volume, p));
    }
    Vec3 n{};
    if (i % 8 != 0) {
      do n = Vec3{2 * rng.uniform01() - 1, 2 * rng.uniform01() - 1, 2 * rng.uniform01() - 1};
      while (!(length(n) > 0.1 && length(n) <= 1));
      n = normalize(n);
    }
    inside[i] = {p, n};
  });
  out.insert(out.end(), inside.begin(), inside.end());
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
