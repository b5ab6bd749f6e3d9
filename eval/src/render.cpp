#include "cpvs/eval/render.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "cpvs/raytrace/visibility.h"

namespace cpvs {

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
