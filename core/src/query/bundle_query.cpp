#include "cpvs/query/bundle_query.h"


namespace cpvs {

BundleQuery::BundleQuery(const LightBundle& bundle) : lights_(bundle.lights) {
  grids_.reserve(bundle.grids.size());
  for (size_t k = 0; k < bundle.grids.size(); ++k)
    grids_.emplace_back(bundle.grids[k].grid, bundle.grids[k].tanCone, bundle.dag(k));
}

size_t BundleQuery::gridAt(size_t i, const Vec3& p) const {
  const BundleLight& l = lights_.at(i);
  if (l.light.kind == LightKind::Spot) return l.firstGrid;
  return l.firstGrid + size_t(cubeFace(p - l.light.position));
}

}  // namespace cpvs
