#include "cpvs/light_frame.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <numbers>
#include <string>

#include "cpvs/scene.h"

namespace cpvs {

LightFrame LightFrame::fromDirection(const Vec3& d) {
  if (!isFinite(d)) throw InputError("light direction is not finite");
  // Scaled by its largest component first, so that a direction of huge or tiny (even
  // subnormal) components normalizes without overflow or underflow.
  const double m = std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)});
  if (!(m > 0)) throw InputError("light direction is the zero vector");
  const Vec3 scaled = d / m;
  LightFrame f;
  f.dir = scaled / length(scaled);
  // Duff, Burgess, Christensen, Hery, Kensler, Liani, Villemin: "Building an Orthonormal
  // Basis, Revisited" (JCGT 2017). Continuous except at the sign flip, exact everywhere.
  const Vec3& n = f.dir;
  double sign = std::copysign(1.0, n.z);
  double a = -1.0 / (sign + n.z);
  double b = n.x * n.y * a;
  f.u = Vec3(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
  f.v = Vec3(b, sign + n.y * n.y * a, -n.y);
  return f;
}

LightFrame LightFrame::fromElevationAzimuth(double elevationDeg, double azimuthDeg) {
  if (!std::isfinite(elevationDeg) || !std::isfinite(azimuthDeg))
    throw InputError("sun elevation and azimuth must be finite numbers");
  if (elevationDeg < 0.0)
    throw InputError("sun elevation " + std::to_string(elevationDeg) +
                     " deg is below the horizon; give --sun-dir for a light from below");
  if (elevationDeg > 90.0)
    throw InputError("sun elevation " + std::to_string(elevationDeg) + " deg is above 90");
  double el = elevationDeg * std::numbers::pi / 180.0;
  double az = azimuthDeg * std::numbers::pi / 180.0;
  Vec3 towardsSun(std::cos(el) * std::sin(az), std::sin(el), std::cos(el) * std::cos(az));
  return fromDirection(-towardsSun);
}

Vec3 Grid::toVoxel(const Vec3& world) const {
  Vec3 p = world - origin;
  double r = double(resolution());
  return {(dot(p, frame.u) - u0) / extent * r, (dot(p, frame.v) - v0) / extent * r,
          (dot(p, frame.dir) - d0) / depthExtent * r};
}

Vec3 Grid::toWorld(const Vec3& voxel) const {
  double r = double(resolution());
  double lu = u0 + voxel.x / r * extent, lv = v0 + voxel.y / r * extent;
  double ld = d0 + voxel.z / r * depthExtent;
  return origin + frame.u * lu + frame.v * lv + frame.dir * ld;
}

Vec3 Grid::directionToVoxel(const Vec3& w) const {
  double r = double(resolution());
  return {dot(w, frame.u) / extent * r, dot(w, frame.v) / extent * r,
          dot(w, frame.dir) / depthExtent * r};
}

Grid makeGrid(const Scene& scene, const LightFrame& frame, int log2Resolution) {
  if (log2Resolution < kMinLog2Resolution || log2Resolution > kMaxLog2Resolution)
    throw InputError("resolution 2^" + std::to_string(log2Resolution) + " is outside [2^" +
                     std::to_string(kMinLog2Resolution) + ", 2^" +
                     std::to_string(kMaxLog2Resolution) + "]");
  if (scene.triangleCount() == 0) throw InputError("scene '" + scene.name + "' has no triangles");
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  Grid g;
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
  return g;
}

int parseResolution(const std::string& text) {
  std::string t;
  for (char c : text)
    if (!std::isspace(static_cast<unsigned char>(c))) t += c;
  if (t.empty()) throw InputError("resolution is empty");
  uint64_t mult = 1;
  char last = static_cast<char>(std::toupper(static_cast<unsigned char>(t.back())));
  if (last == 'K') {
    mult = 1024;
    t.pop_back();
  }
  if (t.empty() || t.size() > 9 || !std::all_of(t.begin(), t.end(), ::isdigit))
    throw InputError("resolution '" + text + "' is not a number like 4096 or 16K");
  uint64_t r = std::stoull(t) * mult;
  if (r == 0 || (r & (r - 1)) != 0)
    throw InputError("resolution '" + text + "' is not a power of two");
  int k = 0;
  while ((uint64_t(1) << k) < r) ++k;
  if (k < kMinLog2Resolution || k > kMaxLog2Resolution)
    throw InputError("resolution '" + text + "' is outside the supported range " +
                     std::to_string(1u << kMinLog2Resolution) + " .. " +
                     std::to_string(1u << kMaxLog2Resolution));
  return k;
}

}  // namespace cpvs
