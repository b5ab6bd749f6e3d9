#include "cpvs/bake/camera_views.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <string>

#include "cpvs/base/error.h"
#include "cpvs/base/split_mix64.h"
#include "cpvs/raytrace/exact_caster.h"

namespace cpvs {

namespace {

// Positions a grid or a path step may have along one extent: a cap far beyond any budget,
// so that the counts below cannot overflow before the budget refuses them.
constexpr double kMaxSteps = double(1u << 24);

// Intervals at most `spacing` long that cover `extent` (at least one).
double stepsOver(double extent, double spacing) {
  return std::min(kMaxSteps, std::max(1.0, std::ceil(extent / spacing)));
}

// Seeds of the two draws an independent sample makes, kept apart.
constexpr uint64_t kPositionStream = 0x5ca1ab1e, kRayStream = 0xfacade;

}  // namespace

double cameraSpacing(const ReceiverDeclaration& d) {
  return d.cameraSpacing > 0 ? d.cameraSpacing : d.viewDistance * kDefaultCameraSpacingShare;
}

uint32_t cameraRaysPerSide(const ReceiverDeclaration& d) { return d.cameraRays ? d.cameraRays : kDefaultCameraRays; }

double cameraPositionCount(const ReceiverDeclaration& d) {
  const double s = cameraSpacing(d);
  double count = double(d.cameraPoints.size());
  for (const auto& [lo, hi] : d.cameraRegions)
    count += (stepsOver(hi.x - lo.x, s) + 1) * (stepsOver(hi.y - lo.y, s) + 1) * (stepsOver(hi.z - lo.z, s) + 1);
  for (const auto& path : d.cameraPaths) {
    count += 1;
    for (size_t i = 1; i < path.size(); ++i) count += stepsOver(length(path[i] - path[i - 1]), s);
  }
  return count;
}

void checkCameraBudget(const ReceiverDeclaration& d) {
  if (d.kind != ReceiverKind::Cameras || d.cameraVisibility != CameraVisibility::Sampled) return;
  const double count = cameraPositionCount(d), rays = 6.0 * cameraRaysPerSide(d) * cameraRaysPerSide(d);
  char text[320];
  if (count > double(kMaxCameraPositions) || count * rays > double(kMaxCameraSampleRays)) {
    std::snprintf(text, sizeof text,
                  "receivers: sampled cameras would cast from %.6g positions x %.6g rays, more than %.6g positions or "
                  "%.6g rays: raise the camera spacing (now %.6g) or lower the rays per face (now %u)",
                  count, rays, double(kMaxCameraPositions), double(kMaxCameraSampleRays), cameraSpacing(d),
                  cameraRaysPerSide(d));
    throw InputError(text);
  }
}

std::vector<Vec3> cameraPositions(const ReceiverDeclaration& d, uint64_t seed) {
  const double s = cameraSpacing(d);
  checkCameraBudget(d);  // before anything is allocated
  const double count = cameraPositionCount(d);
  std::vector<Vec3> out;
  out.reserve(size_t(count));
  // A position's own random stream: the sample does not depend on the order of the places.
  auto jitter = [&](uint64_t item, int axis) {
    SplitMix64 r = SplitMix64::forItem(seed * 0x9E3779B97F4A7C15ull + kPositionStream, 3 * item + uint64_t(axis));
    return r.uniform01() - 0.5;
  };
  for (const Vec3& p : d.cameraPoints) out.push_back(p);
  for (const auto& [lo, hi] : d.cameraRegions) {
    const double n[3] = {stepsOver(hi.x - lo.x, s), stepsOver(hi.y - lo.y, s), stepsOver(hi.z - lo.z, s)};
    for (double i = 0; i <= n[0]; ++i)
      for (double j = 0; j <= n[1]; ++j)
        for (double k = 0; k <= n[2]; ++k) {
          const double f[3] = {i / n[0], j / n[1], k / n[2]};
          Vec3 p;
          double* c = &p.x;
          for (int a = 0; a < 3; ++a) {
            double g = f[a];
            if (seed) g = std::clamp(g + jitter(out.size(), a) / n[a], 0.0, 1.0);
            c[a] = lo[a] + (hi[a] - lo[a]) * g;
          }
          out.push_back(p);
        }
  }
  for (const auto& path : d.cameraPaths) {
    out.push_back(path[0]);
    for (size_t i = 1; i < path.size(); ++i) {
      const Vec3 a = path[i - 1], b = path[i];
      const double n = stepsOver(length(b - a), s);
      for (double j = 1; j <= n; ++j) {
        double g = j / n;
        if (seed) g = std::clamp(g + jitter(out.size(), 0) / n, 0.0, 1.0);
        out.push_back(a + (b - a) * g);
      }
    }
  }
  return out;
}

CameraViews sampleCameraViews(const Scene& scene, const ReceiverDeclaration& d, uint64_t seed,
                              const std::vector<uint8_t>* declared) {
  CameraViews v;
  const std::vector<Vec3> positions = cameraPositions(d, seed);
  const ExactCaster caster(scene);
  const uint32_t R = cameraRaysPerSide(d);
  const size_t n = scene.triangleCount();
  v.sides.assign(n, 0);
  v.positions = positions.size();
  std::atomic<uint64_t> rays{0}, hits{0}, outside{0};
  // One task per position and cube face; each ray's hit side is or-ed in: any order gives
  // the same sides.
  tbb::parallel_for(tbb::blocked_range<size_t>(0, positions.size() * 6), [&](const tbb::blocked_range<size_t>& r) {
    uint64_t localRays = 0, localHits = 0, localOutside = 0;
    for (size_t task = r.begin(); task != r.end(); ++task) {
      const Vec3& o = positions[task / 6];
      const int face = int(task % 6), axis = face / 2;
      const double sign = face % 2 ? -1.0 : 1.0;
      for (uint32_t i = 0; i < R; ++i)
        for (uint32_t j = 0; j < R; ++j) {
          double fu = 0.5, fv = 0.5;
          if (seed) {
            SplitMix64 g = SplitMix64::forItem(seed * 0x9E3779B97F4A7C15ull + kRayStream, (uint64_t(task) * R + i) * R + j);
            fu = g.uniform01(), fv = g.uniform01();
          }
          const double u = (i + fu) / R * 2 - 1, w = (j + fv) / R * 2 - 1;
          double c[3];
          c[axis] = sign;
          c[(axis + 1) % 3] = u;
          c[(axis + 2) % 3] = w;
          const Vec3 dir{c[0], c[1], c[2]};
          const double tMax = d.viewDistance / std::sqrt(dot(dir, dir));
          ++localRays;
          const ExactCaster::Hit hit = caster.firstHit(o, dir, tMax);
          if (hit.triangle == ExactCaster::kNoHit) continue;
          if (scene.closed[hit.triangle] && !hit.front) continue;  // inside a solid: nothing receives there
          const uint8_t side = hit.front ? 1 : 2;
          ++localHits;
          if (declared && (side & ~(*declared)[hit.triangle])) ++localOutside;
          std::atomic_ref<uint8_t>(v.sides[hit.triangle]).fetch_or(side, std::memory_order_relaxed);
        }
    }
    rays += localRays, hits += localHits, outside += localOutside;
  });
  v.rays = rays, v.hits = hits, v.hitsOutside = outside;
  if (declared)
    for (size_t t = 0; t < n; ++t) {
      const double area = triangleArea(scene, t);
      const uint8_t mine = (*declared)[t];
      v.areaDeclared += area * ((mine & 1) + (mine >> 1 & 1));
      const uint8_t extra = v.sides[t] & ~mine;
      v.areaOutside += area * ((extra & 1) + (extra >> 1 & 1));
    }
  return v;
}

}  // namespace cpvs
