#include "cpvs/light/perspective_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "cpvs/base/error.h"
#include "cpvs/base/limits.h"
#include "cpvs/light/lookup_mapping.h"

namespace cpvs {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// tan 85°: wider cones leave too few texels to the axis (and a cube of spot grids needs 45°).
constexpr double kMaxTanHalfFov = 11.430052302761343;

}  // namespace

PerspectiveGrid::PerspectiveGrid(const Vec3& position, const LightFrame& frame, double tanHalfFov, double near,
                                 double far, int log2Resolution)
    : position_(position), frame_(frame), tanHalfFov_(tanHalfFov), near_(near), far_(far), log2Resolution_(log2Resolution) {
  auto fail = [](const std::string& what) { throw InputError("spot light grid: " + what); };
  if (!isFinite(position)) fail("the light's position is not finite");
  for (const Vec3* a : {&frame.dir, &frame.u, &frame.v})
    if (!isFinite(*a) || std::abs(length(*a) - 1) > kUnitDirectionTolerance) fail("the light frame is not orthonormal");
  if (std::abs(dot(frame.dir, frame.u)) > kUnitDirectionTolerance ||
      std::abs(dot(frame.dir, frame.v)) > kUnitDirectionTolerance ||
      std::abs(dot(frame.u, frame.v)) > kUnitDirectionTolerance)
    fail("the light frame is not orthonormal");
  // (tan of 85° in double may round a hair above the constant.)
  if (!(tanHalfFov > 0) || !(tanHalfFov <= kMaxTanHalfFov * (1 + 1e-12)))
    fail("the field of view must be wider than 0 and at most 170 degrees (tan of its half " + std::to_string(tanHalfFov) +
         ")");
  if (!(near > 0) || !std::isfinite(far) || !(near < far))
    fail("near " + std::to_string(near) + " and far " + std::to_string(far) + " must satisfy 0 < near < far");
  if (log2Resolution < kMinLog2Resolution || log2Resolution > kMaxLog2Resolution)
    fail("resolution 2^" + std::to_string(log2Resolution) + " is outside [2^" + std::to_string(kMinLog2Resolution) +
         ", 2^" + std::to_string(kMaxLog2Resolution) + "]");
  logRatio_ = std::log(far / near);
  const uint64_t R = resolution();
  auto table = std::make_shared<std::vector<double>>(R + 1);
  std::vector<double>& b = *table;
  for (uint64_t k = 0; k <= R; ++k) b[k] = near * std::exp(logRatio_ * (double(k) / double(R)));
  b[0] = near;
  b[R] = far;
  for (uint64_t k = 0; k < R; ++k)
    if (!(b[k] < b[k + 1]))
      fail("near " + std::to_string(near) + " and far " + std::to_string(far) + " are too close for " +
           std::to_string(R) + " slices");
  boundaries_ = std::move(table);
}

uint32_t PerspectiveGrid::sliceOfDepth(double zv) const {
  const uint64_t R = resolution();
  if (!(zv >= near_)) return 0;
  if (zv >= far_) return uint32_t(R);
  const std::vector<double>& b = *boundaries_;
  // Eq. (1) gives the slice to within one; the table decides, so every caller agrees.
  const double estimate = std::floor(double(R) * (std::log(zv / near_) / logRatio_));
  uint64_t k = estimate >= 0 ? std::min<uint64_t>(uint64_t(estimate), R - 1) : 0;
  while (k > 0 && zv < b[k]) --k;
  while (k + 1 < R && zv >= b[k + 1]) ++k;
  return uint32_t(k);
}

double PerspectiveGrid::voxelZ(double zv) const {
  const std::vector<double>& b = *boundaries_;
  const uint64_t R = resolution();
  if (zv < near_) return (zv - b[0]) / (b[1] - b[0]);
  if (zv >= far_) return double(R) + (zv - b[R]) / (b[R] - b[R - 1]);
  const uint32_t k = sliceOfDepth(zv);
  const double within = (zv - b[k]) / (b[k + 1] - b[k]);
  // Rounding may reach 1 just below the next boundary: the point stays in slice k.
  return double(k) + std::min(within, std::nextafter(1.0, 0.0));
}

double PerspectiveGrid::voxelZ(double zv, uint32_t& hint) const {
  const std::vector<double>& b = *boundaries_;
  const uint64_t R = resolution();
  if (zv < near_) return (zv - b[0]) / (b[1] - b[0]);
  if (zv >= far_) return double(R) + (zv - b[R]) / (b[R] - b[R - 1]);
  // A few steps through the table from the hint; farther, eq. (1)'s estimate. The table
  // decides either way: the same slice as sliceOfDepth.
  uint64_t k = std::min<uint64_t>(hint, R - 1);
  int steps = 0;
  while (k > 0 && zv < b[k])
    if (--k, ++steps > 8) k = sliceOfDepth(zv);
  while (k + 1 < R && zv >= b[k + 1])
    if (++k, ++steps > 8) k = sliceOfDepth(zv);
  hint = uint32_t(k);
  const double within = (zv - b[k]) / (b[k + 1] - b[k]);
  return double(k) + std::min(within, std::nextafter(1.0, 0.0));
}

double PerspectiveGrid::depthOfVoxelZ(double z) const {
  const std::vector<double>& b = *boundaries_;
  const uint64_t R = resolution();
  if (!(z >= 0)) return b[0] + z * (b[1] - b[0]);
  if (z >= double(R)) return b[R] + (z - double(R)) * (b[R] - b[R - 1]);
  const uint64_t k = uint64_t(z);
  return b[k] + (z - double(k)) * (b[k + 1] - b[k]);
}

Vec3 PerspectiveGrid::voxelFromWorld(const Vec3& world) const {
  const Vec3 q = world - position_;
  const double zv = dot(q, frame_.dir);
  if (!(zv > 0)) return {kNaN, kNaN, kNaN};
  const double half = double(resolution()) * 0.5;
  const double scale = half / tanHalfFov_;
  return {dot(q, frame_.u) / zv * scale + half, dot(q, frame_.v) / zv * scale + half, voxelZ(zv)};
}

Vec3 PerspectiveGrid::worldFromVoxel(const Vec3& voxel) const {
  const double zv = depthOfVoxelZ(voxel.z);
  const double xv = planeCoordinate(voxel.x) * zv, yv = planeCoordinate(voxel.y) * zv;
  return position_ + frame_.u * xv + frame_.v * yv + frame_.dir * zv;
}

TexelRay PerspectiveGrid::texelRay(uint64_t x, uint64_t y, const Vec3& relativeTo) const {
  const double a = planeCoordinate(double(x) + 0.5), b = planeCoordinate(double(y) + 0.5);
  // The far end lies a hair beyond the grid so that a surface on its last slice is hit.
  return {position_ - relativeTo, frame_.dir + frame_.u * a + frame_.v * b, far_ * 1.0001};
}

double PerspectiveGrid::depthOf(const Vec3& world) const { return dot(world - position_, frame_.dir); }

PerspectiveGrid::Local PerspectiveGrid::localAt(const Vec3& world) const {
  const Vec3 q = world - position_;
  const double zv = dot(q, frame_.dir);
  // dZ/dzv of voxelZ: one over the thickness of the slice that holds zv (the first and
  // last slices' beyond near and far, where voxelZ extends them).
  const std::vector<double>& b = *boundaries_;
  const uint64_t R = resolution();
  const uint64_t k = !(zv >= near_) ? 0 : zv >= far_ ? R - 1 : sliceOfDepth(zv);
  return {q, zv, double(R) * 0.5 / (tanHalfFov_ * zv), 1 / (b[k + 1] - b[k])};
}

Vec3 PerspectiveGrid::directionToVoxel(const Vec3& world, const Vec3& w) const {
  const Local l = localAt(world);
  if (!(l.zv > 0)) return {kNaN, kNaN, kNaN};
  const double wd = dot(w, frame_.dir);
  const double x = (dot(w, frame_.u) - dot(l.q, frame_.u) / l.zv * wd) * l.texelsPerUnit;
  const double y = (dot(w, frame_.v) - dot(l.q, frame_.v) / l.zv * wd) * l.texelsPerUnit;
  return {x, y, wd * l.slicesPerUnit};
}

Vec3 PerspectiveGrid::normalToVoxel(const Vec3& world, const Vec3& n) const {
  const Local l = localAt(world);
  if (!(l.zv > 0)) return {kNaN, kNaN, kNaN};
  // J's rows are a(u - xi d), a(v - eta d) and c d (xi = xv / zv, eta = yv / zv, a texels
  // and c slices per world unit); m = J^-T n solves J^T m = n, by its dot products with
  // u, v and d.
  const double nu = dot(n, frame_.u), nv = dot(n, frame_.v);
  const double xi = dot(l.q, frame_.u) / l.zv, eta = dot(l.q, frame_.v) / l.zv;
  return {nu / l.texelsPerUnit, nv / l.texelsPerUnit, (dot(n, frame_.dir) + xi * nu + eta * nv) / l.slicesPerUnit};
}

Vec3 PerspectiveGrid::offsetVoxel(const Vec3& world, const Vec3& normal, double voxels) const {
  const Vec3 c = voxelFromWorld(world);
  if (normal == Vec3{}) return c;
  return offsetAlongNormal(c, normalToVoxel(world, normal), voxels);
}

bool PerspectiveGrid::insideCone(const Vec3& world, double tanCone) const {
  const Vec3 q = world - position_;
  const double zv = dot(q, frame_.dir), a = dot(q, frame_.u), b = dot(q, frame_.v);
  return zv > 0 && a * a + b * b <= tanCone * tanCone * zv * zv;
}


}  // namespace cpvs
