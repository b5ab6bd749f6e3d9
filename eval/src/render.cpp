#include "cpvs/eval/render.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "cpvs/eval/verify.h"
#include "cpvs/base/parse.h"
#include "cpvs/base/split_mix64.h"

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

namespace {

/// A camera's primary rays: the direction through a point of its image.
class CameraRays {
 public:
  CameraRays(const Camera& camera, double aspect) : eye_(camera.eye), aspect_(aspect) {
    forward_ = normalize(camera.target - camera.eye);
    right_ = cross(forward_, camera.up);
    if (length(right_) < 1e-9) right_ = cross(forward_, Vec3{1, 0, 0});
    right_ = normalize(right_);
    up_ = cross(right_, forward_);
    tanHalf_ = std::tan(camera.fovDeg * 0.5 * std::numbers::pi / 180);
  }
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

}  // namespace

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

std::vector<SurfaceSample> sampleCameraViews(const Scene& scene, const RayScene& rays,
                                             const std::vector<Camera>& cameras, double aspect, uint64_t count,
                                             uint64_t seed) {
  if (cameras.empty()) throw InputError("camera sampling needs at least one camera");
  if (!(aspect > 0) || !std::isfinite(aspect)) throw InputError("camera sampling: aspect must be positive");
  std::vector<CameraRays> views;
  for (const Camera& c : cameras) views.emplace_back(c, aspect);
  std::vector<SurfaceHit> hits(count);
  tbb::parallel_for(uint64_t(0), count, [&](uint64_t i) {
    const CameraRays& view = views[i % views.size()];
    SplitMix64 rng = SplitMix64::forItem(seed, i);
    for (int attempt = 0; attempt < kCameraSampleAttempts; ++attempt) {
      const double ix = rng.uniform01(), iy = rng.uniform01();
      if (firstSurface(scene, rays, view.eye(), view.through(ix, iy), hits[i])) break;
    }
  });
  std::vector<SurfaceSample> out;
  out.reserve(count);
  for (const SurfaceHit& h : hits)
    if (h.hit) out.push_back({h.point, h.normal});
  return out;
}

std::vector<float> cpvsVisibility(const CameraHits& hits, const ShadowQuery& query, int pcf) {
  std::vector<float> vis(hits.pixels.size(), 1.0f);
  tbb::parallel_for(size_t(0), hits.pixels.size(), [&](size_t i) {
    const SurfaceHit& s = hits.pixels[i];
    if (s.hit) vis[i] = query.filtered(s.point, s.normal, pcf);
  });
  return vis;
}

std::vector<float> exactVisibility(const CameraHits& hits, const RayScene& rays, const OrthoGrid& grid) {
  std::vector<float> vis(hits.pixels.size(), 1.0f);
  const double epsilon = 1e-5 * (grid.extent + grid.depthExtent);
  tbb::parallel_for(size_t(0), hits.pixels.size(), [&](size_t i) {
    const SurfaceHit& s = hits.pixels[i];
    if (s.hit) vis[i] = exactlyLit(rays, grid, s.point + s.normal * epsilon) ? 1.0f : 0.0f;
  });
  return vis;
}

namespace {

constexpr float kAlbedo = 0.75f;

Rgb sky(int y, int height) {
  float t = float(y) / float(std::max(1, height - 1));
  return {0.35f + 0.3f * t, 0.5f + 0.25f * t, 0.8f + 0.1f * t};
}

float ambient(const Vec3& n) { return 0.12f + 0.08f * float(n.y); }

}  // namespace

Image shadeHits(const CameraHits& hits, const std::vector<float>& visibility, const Vec3& lightDir) {
  Image img(hits.width, hits.height);
  for (int y = 0; y < hits.height; ++y)
    for (int x = 0; x < hits.width; ++x) {
      size_t i = size_t(y) * size_t(hits.width) + size_t(x);
      const SurfaceHit& s = hits.pixels[i];
      if (!s.hit) {
        img.at(x, y) = sky(y, hits.height);
        continue;
      }
      float sun = float(std::max(0.0, -dot(s.normal, lightDir))) * visibility[i];
      float l = kAlbedo * (ambient(s.normal) + 0.9f * sun);
      img.at(x, y) = {l * 1.0f, l * 0.97f, l * 0.9f};  // slightly warm sunlight
    }
  return img;
}

Image differenceImage(const CameraHits& hits, const std::vector<float>& a, const std::vector<float>& b,
                      const Vec3& lightDir, uint64_t* compared, uint64_t* differing) {
  Image img(hits.width, hits.height);
  uint64_t n = 0, d = 0;
  for (int y = 0; y < hits.height; ++y)
    for (int x = 0; x < hits.width; ++x) {
      size_t i = size_t(y) * size_t(hits.width) + size_t(x);
      const SurfaceHit& s = hits.pixels[i];
      if (!s.hit) {
        img.at(x, y) = {0.02f, 0.02f, 0.02f};
        continue;
      }
      float cosSun = float(std::max(0.0, -dot(s.normal, lightDir)));
      float grey = 0.02f + 0.05f * cosSun;
      img.at(x, y) = {grey, grey, grey};
      if (cosSun <= 0) continue;  // the sun cannot reach it either way
      ++n;
      float delta = a[i] - b[i];
      if (std::abs(delta) > 0.5f) ++d;
      if (delta < 0) img.at(x, y) = {-delta, 0.02f, 0.02f};
      if (delta > 0) img.at(x, y) = {0.02f, 0.3f * delta, delta};
    }
  if (compared) *compared = n;
  if (differing) *differing = d;
  return img;
}

}  // namespace cpvs
