// An area light (a window, a sky portal, a light panel) as a set of virtual point lights
// (seed 002, NOTES §3.4): K points on its rectangle, each a small cube of perspective
// grids baked into the light bundle like a point light, and soft visibility as their
// weighted average (BundleQuery::softVisibility).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cpvs/base/vec3.h"
#include "cpvs/light/light.h"

namespace cpvs {

/// The most VPLs one area light takes, and the default.
constexpr uint32_t kMaxVpls = 1024;
constexpr uint32_t kDefaultVpls = 64;
/// A VPL's grids: 2^7 = 128 a side by default (seed 002: "128 in all dimensions works
/// well"), 2^4 to 2^10.
constexpr int kDefaultVplLog2Resolution = 7;
constexpr int kMinVplLog2Resolution = 4, kMaxVplLog2Resolution = 10;

/// A one-sided rectangular emitter: the points centre + s edgeU + t edgeV, s and t in
/// [-1/2, 1/2], shining towards edgeU x edgeV.
struct AreaLight {
  std::string name;
  Vec3 centre, edgeU, edgeV;
  uint32_t vpls = kDefaultVpls;
  int log2Resolution = kDefaultVplLog2Resolution;
  uint64_t seed = 0;         // of the VPLs' placement and rolls
  /// Each VPL's cube, one face along the emitter's normal, turned about it by a seeded
  /// angle and tilted by a seeded fraction of a texel, so that the VPLs' texels fall at
  /// unrelated angles and sub-texel phases and their voxel errors do not line up (seed
  /// 002's decorrelated frames). Off: every cube along the world's axes.
  bool roll = true;
  Vec3 colour{1, 1, 1};      // linear RGB, for shading only
  double intensity = 1;      // the whole emitter's, shared by its VPLs
  double range = 0;          // how far its light reaches; 0: the scene's far side
  Vec3 normal() const { return normalize(cross(edgeU, edgeV)); }
};

/// InputError naming `source` for a degenerate rectangle (edges zero, parallel or not
/// finite), a VPL count outside [1, kMaxVpls], a resolution outside
/// [2^kMinVplLog2Resolution, 2^kMaxVplLog2Resolution], or a centre outside the scene's
/// bounds [lo, hi] (checkLight's margin).
void checkAreaLight(const AreaLight& area, const Vec3& lo, const Vec3& hi, const std::string& source);

/// "CX,CY,CZ:UX,UY,UZ:VX,VY,VZ[:K[:RES]]": the centre, the two edges (the light shines
/// towards U x V), the VPL count and their grids' resolution; InputError naming the flag.
AreaLight parseAreaLightFlag(const std::string& text);

/// Its VPLs, as the bundle's lights: point lights (a cube of grids each, at the area
/// light's resolution) whose direction is the emitter's normal, each 1/K of its intensity,
/// named "NAME vpl i", their `area` the given one (1-based). Placed by a 2-D Halton
/// sequence (bases 2 and 3) under a seeded Cranley-Patterson rotation, so that K VPLs
/// sample the rectangle evenly and two seeds give uncorrelated sets; lifted off the
/// emitter along its normal by a hair (1e-4 of its size), so that the emitter's own
/// geometry does not shadow its light; each one's cube rolled unless `roll` is off.
std::vector<Light> vplsOf(const AreaLight& area, uint32_t areaNumber);

/// The VPLs of every one of `areas`, area light k numbered k + 1, in their order.
std::vector<Light> vplsOf(const std::vector<AreaLight>& areas);

/// How much VPL (or any point light) at x facing `emitterNormal` sends to point p with
/// normal n (zero: no receiver cosine): cos at the emitter times cos at the receiver over
/// the squared distance; 0 behind either. The weight of the VPL in a soft lookup.
double vplWeight(const Vec3& x, const Vec3& emitterNormal, const Vec3& p, const Vec3& n);

}  // namespace cpvs
