#include <array>

#include "cpvs/eval/render.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "cpvs/base/error.h"
#include "cpvs/raytrace/visibility.h"

namespace cpvs {

std::vector<float> cpvsVisibility(const CameraHits& hits, const ShadowQuery& query, int pcf) {
  return lookupVisibility(hits, query, pcf);
}

std::vector<float> exactVisibility(const CameraHits& hits, const RayScene& rays, const OrthoGrid& grid) {
  std::vector<float> vis(hits.pixels.size(), 1.0f);
  const double epsilon = 1e-5 * (grid.extent + grid.sceneDepthExtent());
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

// The sun's irradiance in shadeHits's units: a white Lambertian surface facing it has
// radiance albedo * E / pi = 0.9 albedo.
constexpr double kSunIrradiance = 0.9 * std::numbers::pi;
// Sky light scattered by the medium, as radiance: about the sky's ambient level.
constexpr Rgb kSkyInScatter{0.09f, 0.11f, 0.14f};

// The stretch [t0, t1] of the ray from `from` along `dir` inside the box [lo, hi]; empty
// (t0 > t1) when it misses the box.
std::pair<double, double> boxSpan(const Vec3& from, const Vec3& dir, const Vec3& lo, const Vec3& hi) {
  double tIn = 0, tOut = std::numeric_limits<double>::infinity();
  const double f[3] = {from.x, from.y, from.z}, d[3] = {dir.x, dir.y, dir.z}, l[3] = {lo.x, lo.y, lo.z},
               h[3] = {hi.x, hi.y, hi.z};
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0) {
      if (f[a] < l[a] || f[a] > h[a]) return {1, 0};
      continue;
    }
    double t0 = (l[a] - f[a]) / d[a], t1 = (h[a] - f[a]) / d[a];
    if (t0 > t1) std::swap(t0, t1);
    tIn = std::max(tIn, t0);
    tOut = std::min(tOut, t1);
  }
  return {tIn, tOut};
}

// A view ray's stretch in the fog layer [t0, t1] (to its hit) and, within it, in the
// scene's box [w0, w1] (empty: w0 >= w1), along eye + t dir.
struct FogSpan {
  double t0, t1, w0, w1;
};
FogSpan fogSpan(const Vec3& eye, const Vec3& dir, const SurfaceHit& s, const Vec3& lo, const Vec3& hi) {
  const double inf = std::numeric_limits<double>::infinity();
  auto [t0, t1] = boxSpan(eye, dir, {-inf, lo.y, -inf}, {inf, hi.y, inf});
  if (s.hit) t1 = std::min(t1, dot(s.point - eye, dir));
  const auto [b0, b1] = boxSpan(eye, dir, lo, hi);
  return {t0, t1, std::max(t0, b0), std::min(t1, b1)};
}

}  // namespace

void fogSegments(const CameraHits& hits, const Camera& camera, const Vec3& lo, const Vec3& hi, std::vector<Vec3>& from,
                 std::vector<Vec3>& to) {
  const CameraRays rays(camera, double(hits.width) / double(hits.height));
  from.assign(hits.pixels.size(), rays.eye());
  to.assign(hits.pixels.size(), rays.eye());
  tbb::parallel_for(0, hits.height, [&](int y) {
    for (int x = 0; x < hits.width; ++x) {
      const size_t i = size_t(y) * size_t(hits.width) + size_t(x);
      const Vec3 eye = rays.eye(), dir = rays.through((x + 0.5) / hits.width, (y + 0.5) / hits.height);
      const FogSpan f = fogSpan(eye, dir, hits.pixels[i], lo, hi);
      if (f.t0 < f.t1 && f.w0 < f.w1) from[i] = eye + dir * f.w0, to[i] = eye + dir * f.w1;
    }
  });
}

Image foggedImage(const Image& clear, const CameraHits& hits, const Camera& camera, const ShadowQuery& query,
                  const Medium& medium, const Vec3& lo, const Vec3& hi, const std::vector<float>* boxInScattering) {
  checkMedium(medium);
  CPVS_CHECK(!boxInScattering || boxInScattering->size() == hits.pixels.size());
  const double sigma = medium.extinction();
  if (sigma == 0) return clear;  // nothing in the air
  const CameraRays rays(camera, double(hits.width) / double(hits.height));
  const Vec3 sunDir = query.grid().frame.dir;
  Image img(hits.width, hits.height);
  tbb::parallel_for(0, hits.height, [&](int y) {
    for (int x = 0; x < hits.width; ++x) {
      const size_t i = size_t(y) * size_t(hits.width) + size_t(x);
      const SurfaceHit& s = hits.pixels[i];
      const Rgb c = clear.pixels[i];
      const Vec3 eye = rays.eye(), dir = rays.through((x + 0.5) / hits.width, (y + 0.5) / hits.height);
      // The ray's stretch in the layer, then in the scene's box (which the grid covers):
      // past the box the sun reaches every point, in closed form.
      const auto [t0, t1, w0, w1] = fogSpan(eye, dir, s, lo, hi);
      if (!(t0 < t1)) {
        img.at(x, y) = c;
        continue;
      }
      double sun = 0;
      if (w0 < w1) {
        const double box = boxInScattering ? double((*boxInScattering)[i])
                                           : query.inScattering(eye + dir * w0, eye + dir * w1, medium).inScattering;
        sun += box * std::exp(-sigma * (w0 - t0));
      }
      // The lit rest of the layer before and after the box.
      const double phase = medium.scattering * henyeyGreenstein(medium.g, std::clamp(-dot(sunDir, dir), -1.0, 1.0));
      if (w0 < w1) {
        sun += phase * (attenuatedLength(sigma, 0, w0 - t0) + attenuatedLength(sigma, w1 - t0, t1 - t0));
      } else {
        sun += phase * attenuatedLength(sigma, 0, t1 - t0);
      }
      const float t = float(std::exp(-sigma * (t1 - t0)));
      const float sky = float(medium.scattering / sigma) * (1 - t);
      const float f = float(kSunIrradiance * sun);
      img.at(x, y) = {c.r * t + f * 1.0f + sky * kSkyInScatter.r, c.g * t + f * 0.97f + sky * kSkyInScatter.g,
                      c.b * t + f * 0.9f + sky * kSkyInScatter.b};
    }
  });
  return img;
}

Image shadeHits(const CameraHits& hits, const std::vector<float>& visibility, const Vec3& lightDir,
                const std::vector<std::array<float, 3>>* transmittance) {
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
      if (!transmittance) {
        float l = kAlbedo * (ambient(s.normal) + 0.9f * sun);
        img.at(x, y) = {l * 1.0f, l * 0.97f, l * 0.9f};  // slightly warm sunlight
        continue;
      }
      // The sun through translucent casters, tinted channel by channel.
      const std::array<float, 3>& t = (*transmittance)[i];
      const float a = ambient(s.normal);
      img.at(x, y) = {kAlbedo * (a + 0.9f * sun * t[0]) * 1.0f, kAlbedo * (a + 0.9f * sun * t[1]) * 0.97f,
                      kAlbedo * (a + 0.9f * sun * t[2]) * 0.9f};
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
