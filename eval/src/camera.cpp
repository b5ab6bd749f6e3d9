#include "cpvs/eval/camera.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "cpvs/base/error.h"
#include "cpvs/base/parse.h"

namespace cpvs {

Camera Camera::parse(const std::string& text) {
  const std::vector<double> v = parseNumbers(text, "camera '" + text + "'");
  if (v.size() != 6 && v.size() != 7)
    throw InputError("camera '" + text + "': expected EX,EY,EZ,TX,TY,TZ[,FOV], got " + std::to_string(v.size()) +
                     " numbers");
  Camera c;
  c.eye = {v[0], v[1], v[2]};
  c.target = {v[3], v[4], v[5]};
  if (v.size() == 7) c.fovDeg = v[6];
  if (!(c.fovDeg > 1 && c.fovDeg < 179)) throw InputError("camera '" + text + "': field of view must be in (1, 179)");
  if (length(c.target - c.eye) <= 0) throw InputError("camera '" + text + "': eye and target coincide");
  return c;
}

Camera defaultCamera(const Scene& scene, const Vec3& lightDir, double aspect) {
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  Vec3 centre = (lo + hi) * 0.5;
  double radius = 0.5 * length(hi - lo);
  // From the sun's side, turned 70 degrees about Y and raised 40 degrees: shadows then fall
  // sideways across the picture instead of hiding behind what casts them.
  Vec3 toSun{-lightDir.x, 0, -lightDir.z};
  if (length(toSun) < 1e-3) toSun = {1, 0, 1};
  toSun = normalize(toSun);
  const double turn = 70 * std::numbers::pi / 180, rise = 40 * std::numbers::pi / 180;
  Vec3 side{toSun.x * std::cos(turn) - toSun.z * std::sin(turn), 0, toSun.x * std::sin(turn) + toSun.z * std::cos(turn)};
  Vec3 dir = side * std::cos(rise) + Vec3{0, std::sin(rise), 0};
  Camera c;
  double halfFov = std::min(c.fovDeg, c.fovDeg * aspect) * 0.5 * std::numbers::pi / 180;
  // The bounding sphere is loose for flat scenes: frame it a little tighter than it.
  double distance = radius / std::tan(halfFov) * 0.9;
  c.eye = centre + dir * distance;
  c.target = centre;
  return c;
}

CameraRays::CameraRays(const Camera& camera, double aspect) : eye_(camera.eye), aspect_(aspect) {
  forward_ = normalize(camera.target - camera.eye);
  right_ = cross(forward_, camera.up);
  if (length(right_) < 1e-9) right_ = cross(forward_, Vec3{1, 0, 0});
  right_ = normalize(right_);
  up_ = cross(right_, forward_);
  tanHalf_ = std::tan(camera.fovDeg * 0.5 * std::numbers::pi / 180);
}

/// The first surface along a ray, with its geometric normal turned towards the ray's origin.
bool firstSurface(const Scene& scene, const RayScene& rays, const Vec3& from, const Vec3& dir, SurfaceHit& out) {
  RayHit h;
  if (!rays.intersect(from, dir, 0.0, std::numeric_limits<double>::infinity(), h)) return false;
  Vec3 a = scene.vertex(h.triangle, 0), b = scene.vertex(h.triangle, 1), c = scene.vertex(h.triangle, 2);
  Vec3 n = normalize(cross(b - a, c - a));
  if (dot(n, dir) > 0) n = -n;
  out = {true, from + dir * h.t, n};
  return true;
}

CameraHits traceCamera(const Scene& scene, const RayScene& rays, const Camera& camera, int width, int height) {
  if (width < 1 || height < 1 || width > 16384 || height > 16384)
    throw InputError("image size " + std::to_string(width) + "x" + std::to_string(height) +
                     " must be between 1x1 and 16384x16384");
  CameraHits out;
  out.width = width;
  out.height = height;
  out.pixels.resize(size_t(width) * size_t(height));
  const CameraRays view(camera, double(width) / double(height));
  tbb::parallel_for(0, height, [&](int y) {
    for (int x = 0; x < width; ++x) {
      const Vec3 dir = view.through((x + 0.5) / width, (y + 0.5) / height);
      firstSurface(scene, rays, view.eye(), dir, out.pixels[size_t(y) * size_t(width) + size_t(x)]);
    }
  });
  return out;
}

}  // namespace cpvs
