// Pinhole cameras over a scene: parsed from the command line, a default view, and what
// each pixel sees.
#pragma once

#include <string>
#include <vector>

#include "cpvs/base/vec3.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

/// A pinhole camera; `fovDeg` is the vertical field of view.
struct Camera {
  Vec3 eye, target, up{0, 1, 0};
  double fovDeg = 40;

  /// Parses "EX,EY,EZ,TX,TY,TZ" or "EX,EY,EZ,TX,TY,TZ,FOV"; InputError otherwise.
  static Camera parse(const std::string& text);
};

/// A three-quarter view of the whole scene from its sunny side, Y up.
Camera defaultCamera(const Scene& scene, const Vec3& lightDir, double aspect);

/// What the camera sees through each pixel.
struct SurfaceHit {
  bool hit = false;
  Vec3 point;   // world position
  Vec3 normal;  // unit geometric normal, turned towards the camera
};
struct CameraHits {
  int width = 0, height = 0;
  std::vector<SurfaceHit> pixels;  // row-major, top row first
};

/// A camera's primary rays: the direction through a point of its image.
class CameraRays {
 public:
  CameraRays(const Camera& camera, double aspect);
  const Vec3& eye() const { return eye_; }
  /// Through image point (ix, iy), each in [0, 1], (0, 0) at the top left.
  Vec3 through(double ix, double iy) const {
    const double sx = (ix * 2 - 1) * tanHalf_ * aspect_, sy = (1 - iy * 2) * tanHalf_;
    return normalize(forward_ + right_ * sx + up_ * sy);
  }

 private:
  Vec3 eye_, forward_, right_, up_;
  double aspect_, tanHalf_ = 0;
};

/// The first surface along a ray, with its geometric normal turned towards the ray's
/// origin; false (and `out` untouched) when the ray hits nothing.
bool firstSurface(const Scene& scene, const RayScene& rays, const Vec3& from, const Vec3& dir, SurfaceHit& out);

/// Traces one primary ray per pixel centre, multithreaded.
CameraHits traceCamera(const Scene& scene, const RayScene& rays, const Camera& camera, int width, int height);

}  // namespace cpvs
