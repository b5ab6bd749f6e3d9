// CPU shadow queries of every light of a light bundle: a light's visibility at a point
// is its spot grid's, or for a point light that of the cube face the point falls in.
#pragma once

#include <cstddef>
#include <vector>

#include "cpvs/io/bundle_file.h"
#include "cpvs/query/shadow_query.h"

namespace cpvs {

class BundleQuery {
 public:
  /// One ShadowQuery per grid, each a view of the bundle's shared pool.
  explicit BundleQuery(const LightBundle& bundle);

  size_t lightCount() const { return lights_.size(); }
  const BundleLight& light(size_t i) const { return lights_.at(i); }
  size_t gridCount() const { return grids_.size(); }
  const ShadowQuery& grid(size_t k) const { return grids_.at(k); }
  /// The light grid k belongs to.
  size_t lightOfGrid(size_t k) const { return gridLight_.at(k); }
  /// The grid of light i that answers at world point p (a point light's cube face).
  size_t gridAt(size_t light, const Vec3& p) const;
  /// How far from light i a point may be and still get light: its grids' frusta cut at
  /// far (their corners), plus the widest normal offset a lookup applies there. Every
  /// lookup of a point beyond it answers 0.
  double reach(size_t light) const;

  /// Fraction of the pcf x pcf texels around the lookup voxel of light i's grid at p
  /// that are lit (ShadowQuery::filtered): 0 outside its cone and behind it.
  float filtered(size_t light, const Vec3& p, const Vec3& n, PcfWidth pcf) const {
    return grids_[gridAt(light, p)].filtered(p, n, pcf);
  }
  /// How many of those texels are lit (ShadowQuery::litTexels): what a GPU lookup
  /// (cpvsLightLitTexels) answers.
  uint32_t litTexels(size_t light, const Vec3& p, const Vec3& n, PcfWidth pcf) const {
    return grids_[gridAt(light, p)].litTexels(p, n, pcf);
  }

  /// How many area lights the bundle holds (their VPLs are its lights whose `area` is set).
  size_t areaCount() const { return areaVpls_.size(); }
  /// The lights that are VPLs of area light a (0-based).
  const std::vector<uint32_t>& vplsOf(size_t area) const { return areaVpls_.at(area); }
  /// Soft visibility of area light a at p with normal n (zero: no receiver cosine): the
  /// VPLs' bilinear visibilities (ShadowQuery::bilinearVisibility of the cube face p falls
  /// in) averaged with the weights vplWeight gives them, sum w_i V_i / sum w_i; 0 where no
  /// VPL reaches (behind the emitter, beyond its range). What fraction of the light the
  /// emitter sends to p arrives. Each weight reads the emitter's normal as the GPU's
  /// light table holds it (unit, in floats), so that cpvsSoftVisibility answers the same
  /// to the bit.
  float softVisibility(size_t area, const Vec3& p, const Vec3& n) const;
  /// Light i's emitter normal as a weight reads it: its direction, normalized, rounded
  /// to floats (lightTableBytes's CpvsLight::direction).
  const Vec3& emitterNormal(size_t i) const { return emitterNormal_.at(i); }

 private:
  std::vector<BundleLight> lights_;
  std::vector<ShadowQuery> grids_;
  std::vector<double> reach_;
  std::vector<uint32_t> gridLight_;
  std::vector<std::vector<uint32_t>> areaVpls_;
  std::vector<Vec3> emitterNormal_;
};

}  // namespace cpvs
