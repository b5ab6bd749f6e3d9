#include "cpvs/light/ortho_grid.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <string>

#include "cpvs/base/error.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

OrthoGrid OrthoGrid::withSide(uint64_t side) const {
  if (side < 1 || side > (uint64_t(1) << kMaxLog2Resolution))
    throw InputError("grid side " + std::to_string(side) + " is outside [1, " +
                     std::to_string(uint64_t(1) << kMaxLog2Resolution) + "]");
  OrthoGrid g = *this;
  g.side_ = side;
  return g;
}

LookupMapping OrthoGrid::lookupMapping() const {
  const double r = cells();
  return {{origin.x, origin.y, origin.z}, {frame.u.x, frame.u.y, frame.u.z}, {frame.v.x, frame.v.y, frame.v.z},
          {frame.dir.x, frame.dir.y, frame.dir.z}, {u0, v0, d0}, {r / extent, r / extent, r / depthExtent}};
}

Vec3 OrthoGrid::voxelFromWorld(const Vec3& world) const { return mappedVoxel(lookupMapping(), world); }

Vec3 OrthoGrid::worldFromVoxel(const Vec3& voxel) const {
  const double r = cells();
  const double lu = u0 + voxel.x / r * extent, lv = v0 + voxel.y / r * extent;
  const double ld = d0 + voxel.z / r * depthExtent;
  return origin + frame.u * lu + frame.v * lv + frame.dir * ld;
}

Vec3 OrthoGrid::directionToVoxel(const Vec3& w) const { return mappedDirection(lookupMapping(), w); }

TexelMapping::TexelMapping(const OrthoGrid& g, const Vec3& relativeTo)
    : local0_(g.origin - relativeTo),
      u_(g.frame.u),
      v_(g.frame.v),
      dir_(g.frame.dir),
      u0_(g.u0),
      v0_(g.v0),
      d0_(g.d0),
      texelSize_(g.texelSize()),
      slicesPerUnit_(double(g.side()) / g.depthExtent),
      cells_(double(g.side())),
      // The far end lies a hair beyond the grid so that a surface on its last slice is hit.
      tMax_(g.depthExtent * 1.0001),
      side_(uint32_t(g.side())) {}

TexelRay OrthoGrid::texelRay(uint64_t x, uint64_t y, const Vec3& relativeTo) const {
  return texelMapping(relativeTo).ray(x, y);
}

uint32_t OrthoGrid::sliceOfDepth(double t) const { return texelMapping(origin).slice(t); }

double OrthoGrid::depthOf(const Vec3& world) const { return dot(world - origin, frame.dir) - d0; }

Vec3 OrthoGrid::offsetVoxel(const Vec3& world, const Vec3& normal, double voxels) const {
  return mappedLookup(lookupMapping(), world, normal, voxels, depthShift());
}

void checkGrid(const OrthoGrid& g, const std::string& source) {
  auto fail = [&](const std::string& what) { throw InputError(source + ": " + what); };
  if (g.log2Resolution < kMinLog2Resolution || g.log2Resolution > kMaxLog2Resolution)
    fail("resolution 2^" + std::to_string(g.log2Resolution) + " is out of range");
  for (double v : {g.u0, g.v0, g.d0, g.extent, g.depthExtent})
    if (!std::isfinite(v)) fail("the grid holds a non-finite value");
  if (!(g.extent > 0) || !(g.depthExtent > 0)) fail("the grid's extents are not positive");
  for (const Vec3* v : {&g.frame.dir, &g.frame.u, &g.frame.v, &g.origin})
    if (!isFinite(*v)) fail("the light frame holds a non-finite value");
  if (std::abs(length(g.frame.dir) - 1) > kUnitDirectionTolerance) fail("the light direction is not a unit vector");
  if (g.depthSlices != 0 && (!std::has_single_bit(g.depthSlices) || g.depthSlices >= g.resolution()))
    fail(std::to_string(g.depthSlices) + " depth slices is not a power of two below the resolution");
}

void checkDepthSlices(uint64_t depthSlices, int log2Resolution, const std::string& what) {
  const uint64_t R = uint64_t(1) << log2Resolution;
  if (depthSlices > R)
    throw InputError(what + ": " + std::to_string(depthSlices) + " depth slices is more than the resolution, " +
                     std::to_string(R) + " (0 or " + std::to_string(R) + ": a cubic grid)");
  if (depthSlices != 0 && !std::has_single_bit(depthSlices))
    throw InputError(what + ": " + std::to_string(depthSlices) + " depth slices is not a power of two");
}

int OrthoGrid::depthShift() const {
  if (side_ != 0 || depthSlices == 0) return 0;
  return log2Resolution - std::countr_zero(depthSlices);
}

double OrthoGrid::sceneDepthExtent() const {
  return depthSlices == 0 ? depthExtent : depthExtent * double(depthSlices) / double(resolution());
}

OrthoGrid OrthoGrid::withResolution(int log2R) const {
  OrthoGrid g = *this;
  g.log2Resolution = log2R;
  const int shift = depthShift();
  g.depthSlices = shift == 0 ? 0 : uint32_t(1) << std::max(0, log2R - shift);
  return g;
}

OrthoGrid makeGrid(const Scene& scene, const LightFrame& frame, int log2Resolution, uint64_t depthSlices) {
  if (log2Resolution < kMinLog2Resolution || log2Resolution > kMaxLog2Resolution)
    throw InputError("resolution 2^" + std::to_string(log2Resolution) + " is outside [2^" +
                     std::to_string(kMinLog2Resolution) + ", 2^" +
                     std::to_string(kMaxLog2Resolution) + "]");
  checkDepthSlices(depthSlices, log2Resolution, "depth slices");
  if (scene.triangleCount() == 0) throw InputError("scene '" + scene.name + "' has no triangles");
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  OrthoGrid g;
  g.frame = frame;
  g.log2Resolution = log2Resolution;
  g.origin = (lo + hi) * 0.5;
  double mn[3] = {INFINITY, INFINITY, INFINITY}, mx[3] = {-INFINITY, -INFINITY, -INFINITY};
  const Vec3 axes[3] = {frame.u, frame.v, frame.dir};
  for (uint32_t idx : scene.indices) {
    Vec3 p = scene.positions[idx] - g.origin;
    for (int a = 0; a < 3; ++a) {
      double c = dot(p, axes[a]);
      mn[a] = std::min(mn[a], c);
      mx[a] = std::max(mx[a], c);
    }
  }
  // A margin keeps every surface strictly inside the grid (no hit on the near plane, no
  // texel centre on the outermost vertex); relative to the largest extent so that a flat
  // scene still gets a non-degenerate depth range.
  double span = std::max({mx[0] - mn[0], mx[1] - mn[1], mx[2] - mn[2]});
  if (!(span > 0)) span = std::max(1.0, length(hi - lo));
  double margin = span * 1e-3;
  double side = std::max(mx[0] - mn[0], mx[1] - mn[1]) + 2 * margin;
  double cu = 0.5 * (mn[0] + mx[0]), cv = 0.5 * (mn[1] + mx[1]);
  g.extent = side;
  g.u0 = cu - 0.5 * side;
  g.v0 = cv - 0.5 * side;
  g.d0 = mn[2] - margin;
  g.depthExtent = (mx[2] - mn[2]) + 2 * margin;
  // Slices R / depthSlices times deeper (a power of two: exact), reaching as far behind.
  if (depthSlices != 0 && depthSlices != g.resolution()) {
    g.depthExtent *= double(g.resolution()) / double(depthSlices);
    g.depthSlices = uint32_t(depthSlices);
  }
  // No negative zeros (see LightFrame::fromDirection).
  g.origin = withoutNegativeZeros(g.origin);
  g.u0 += 0.0;
  g.v0 += 0.0;
  g.d0 += 0.0;
  return g;
}

}  // namespace cpvs
