#include "cpvs/query/bundle_query.h"

#include <algorithm>
#include <cmath>

#include "cpvs/light/area_light.h"

namespace cpvs {

BundleQuery::BundleQuery(const LightBundle& bundle) : lights_(bundle.lights) {
  grids_.reserve(bundle.grids.size());
  for (size_t k = 0; k < bundle.grids.size(); ++k) {
    grids_.emplace_back(bundle.grids[k].grid, bundle.grids[k].tanCone, bundle.dag(k));
    gridLight_.push_back(bundle.grids[k].light);
  }
  for (const BundleLight& l : lights_) {
    double r = 0;
    for (uint32_t k = l.firstGrid; k < l.firstGrid + l.gridCount; ++k) {
      const PerspectiveGrid& g = bundle.grids[k].grid;
      const double far = g.far(), t = g.tanHalfFov(), R = double(g.resolution());
      // The widest lit texel's farthest point from the axis (a texel the cone touches is
      // lit as a whole: the cone, widened by a texel's diagonal; at most the frustum's
      // corner) at far, and a voxel there: its width and its depth, along a ray up to
      // `stretch` longer than its view depth.
      const double wide = std::min(bundle.grids[k].tanCone + 2 * std::sqrt(2.0) * t / R, std::sqrt(2.0) * t);
      const double stretch = std::sqrt(1 + wide * wide), corner = far * stretch;
      const double voxel = (2 * far * t / R + (far - g.sliceBoundary(g.resolution() - 1))) * stretch;
      r = std::max(r, corner + 2 * normalOffsetVoxels(kMaxPcfWidth) * voxel);
    }
    reach_.push_back(r);
  }
  for (const BundleLight& l : lights_) {
    const Vec3 d = l.light.kind == LightKind::Spot || l.light.area != 0 ? normalize(l.light.direction) : Vec3{};
    emitterNormal_.push_back({double(float(d.x)), double(float(d.y)), double(float(d.z))});
  }
  for (size_t i = 0; i < lights_.size(); ++i)
    if (const uint32_t a = lights_[i].light.area; a != 0) {
      if (areaVpls_.size() < a) areaVpls_.resize(a);
      areaVpls_[a - 1].push_back(uint32_t(i));
    }
}

float BundleQuery::softVisibility(size_t area, const Vec3& p, const Vec3& n) const {
  double sum = 0, lit = 0;
  for (uint32_t i : areaVpls_.at(area)) {
    const Light& l = lights_[i].light;
    const double w = vplWeight(l.position, emitterNormal_[i], p, n);
    if (w == 0) continue;
    sum += w;
    lit += w * grids_[gridAt(i, p)].bilinearVisibility(p, n);
  }
  return sum > 0 ? float(lit / sum) : 0.0f;
}

double BundleQuery::reach(size_t light) const { return reach_.at(light); }

size_t BundleQuery::gridAt(size_t i, const Vec3& p) const {
  const BundleLight& l = lights_.at(i);
  if (l.light.kind == LightKind::Spot) return l.firstGrid;
  return l.firstGrid + size_t(cubeFace(p - l.light.position, l.light.cube));
}

}  // namespace cpvs
