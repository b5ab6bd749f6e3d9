#include "cpvs/eval/light_render.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "cpvs/base/error.h"

namespace cpvs {

namespace {

constexpr float kAlbedo = 0.7f, kAmbient = 0.01f;
constexpr double kDegrees = 3.14159265358979323846 / 180;

// Light i's visibility at (p, n): its pcf lookup, or for a VPL its area light's soft
// visibility, looked up once a pixel (`soft` holds each area's, NaN until asked).
float visibilityOf(const BundleQuery& query, size_t i, const Vec3& p, const Vec3& n, int pcf, std::vector<float>& soft) {
  const uint32_t area = query.light(i).light.area;
  if (area == 0) return query.filtered(i, p, n, pcf);
  float& v = soft.at(area - 1);
  if (std::isnan(v)) v = query.softVisibility(area - 1, p, n);
  return v;
}

// A pixel of the picture from the lights `each` visits.
template <class EachLight>
Rgb shadePixel(const BundleQuery& query, const SurfaceHit& s, int pcf, EachLight&& each) {
  Rgb sum{kAmbient, kAmbient, kAmbient};
  std::vector<float> soft(query.areaCount(), std::nanf(""));
  each([&](size_t light) {
    const Rgb r = lightRadiance(query, light, s.point, s.normal, visibilityOf(query, light, s.point, s.normal, pcf, soft));
    sum.r += r.r;
    sum.g += r.g;
    sum.b += r.b;
  });
  return {kAlbedo * sum.r, kAlbedo * sum.g, kAlbedo * sum.b};
}

Rgb night() { return {0.004f, 0.005f, 0.012f}; }

}  // namespace

Rgb lightRadiance(const BundleQuery& query, size_t i, const Vec3& p, const Vec3& n, int pcf) {
  std::vector<float> soft(query.areaCount(), std::nanf(""));
  return lightRadiance(query, i, p, n, visibilityOf(query, i, p, n, pcf, soft));
}

Rgb lightRadiance(const BundleQuery& query, size_t i, const Vec3& p, const Vec3& n, float vis) {
  const Light& l = query.light(i).light;
  if (vis == 0) return {};
  const Vec3 toLight = l.position - p;
  const double d = length(toLight);
  if (!(d > 0)) return {};
  const double ndl = std::max(0.0, dot(n, toLight) / d);
  // Fall-off: inverse-square-like near the light, windowed to 0 at its reach.
  const double s = d / query.reach(i), window = std::pow(std::clamp(1 - s * s * s * s, 0.0, 1.0), 2);
  double a = window / (1 + 16 * s * s);
  // A spot light's cone; a point light has none unless it is a spot wider than one grid
  // holds, baked as a cube (sceneLights).
  if (l.kind == LightKind::Spot || l.coneDeg > kMaxConeDeg) {
    const double outer = std::cos(l.coneDeg * kDegrees), inner = std::cos(0.75 * l.coneDeg * kDegrees);
    const double c = dot(normalize(l.direction), toLight / -d);
    const double x = std::clamp((c - outer) / std::max(inner - outer, 1e-9), 0.0, 1.0);
    a *= x * x * (3 - 2 * x);
  }
  // A VPL is a patch of its emitter: cosine-weighted about the emitter's normal.
  if (l.area != 0) a *= std::max(0.0, -dot(query.emitterNormal(i), toLight) / d);
  const float k = float(vis * ndl * a * l.intensity);
  return {k * float(l.colour.x), k * float(l.colour.y), k * float(l.colour.z)};
}

void hitPoints(const CameraHits& hits, std::vector<Vec3>& points, std::vector<uint8_t>& hit) {
  points.resize(hits.pixels.size());
  hit.resize(hits.pixels.size());
  for (size_t i = 0; i < hits.pixels.size(); ++i) {
    points[i] = hits.pixels[i].point;
    hit[i] = hits.pixels[i].hit ? 1 : 0;
  }
}

namespace {

// Every pixel: the night sky where nothing is hit, else the lights `lightsOf(x, y, fn)`
// passes to fn.
template <class LightsOf>
Image shadeEach(const CameraHits& hits, const BundleQuery& query, int pcf, LightsOf&& lightsOf) {
  Image img(hits.width, hits.height);
  tbb::parallel_for(0, hits.height, [&](int y) {
    for (int x = 0; x < hits.width; ++x) {
      const SurfaceHit& s = hits.pixels[size_t(y) * size_t(hits.width) + size_t(x)];
      img.at(x, y) = s.hit ? shadePixel(query, s, pcf, [&](auto&& fn) { lightsOf(x, y, fn); }) : night();
    }
  });
  return img;
}

}  // namespace

Image shadeLightTiles(const CameraHits& hits, const BundleQuery& query, const LightTiles& tiles, int pcf) {
  return shadeEach(hits, query, pcf, [&](int x, int y, auto&& fn) {
    const size_t t = tiles.tile(x, y);
    for (uint32_t k = tiles.begin[t]; k < tiles.begin[t + 1]; ++k) fn(tiles.lights[k]);
  });
}

Image shadeLightTiles(const CameraHits& hits, const BundleQuery& query, const LightTiles& tiles,
                      const std::vector<float>& visibility) {
  // Where each row's lookups begin, so rows shade in parallel.
  std::vector<size_t> rowBegin(size_t(hits.height) + 1, 0);
  for (int y = 0; y < hits.height; ++y) {
    size_t n = 0;
    for (int x = 0; x < hits.width; ++x)
      if (hits.pixels[size_t(y) * size_t(hits.width) + size_t(x)].hit) {
        const size_t t = tiles.tile(x, y);
        n += tiles.begin[t + 1] - tiles.begin[t];
      }
    rowBegin[size_t(y) + 1] = rowBegin[size_t(y)] + n;
  }
  CPVS_CHECK(visibility.size() == rowBegin.back());
  Image img(hits.width, hits.height);
  tbb::parallel_for(0, hits.height, [&](int y) {
    size_t at = rowBegin[size_t(y)];
    for (int x = 0; x < hits.width; ++x) {
      const SurfaceHit& s = hits.pixels[size_t(y) * size_t(hits.width) + size_t(x)];
      if (!s.hit) {
        img.at(x, y) = night();
        continue;
      }
      Rgb sum{kAmbient, kAmbient, kAmbient};
      const size_t t = tiles.tile(x, y);
      for (uint32_t k = tiles.begin[t]; k < tiles.begin[t + 1]; ++k) {
        const Rgb r = lightRadiance(query, tiles.lights[k], s.point, s.normal, visibility[at++]);
        sum.r += r.r;
        sum.g += r.g;
        sum.b += r.b;
      }
      img.at(x, y) = {kAlbedo * sum.r, kAlbedo * sum.g, kAlbedo * sum.b};
    }
  });
  return img;
}

void tileLookups(const CameraHits& hits, const LightTiles& tiles, std::vector<uint32_t>& lights,
                 std::vector<Vec3>& points, std::vector<Vec3>& normals) {
  lights.clear(), points.clear(), normals.clear();
  for (int y = 0; y < hits.height; ++y)
    for (int x = 0; x < hits.width; ++x) {
      const SurfaceHit& s = hits.pixels[size_t(y) * size_t(hits.width) + size_t(x)];
      if (!s.hit) continue;
      const size_t t = tiles.tile(x, y);
      for (uint32_t k = tiles.begin[t]; k < tiles.begin[t + 1]; ++k) {
        lights.push_back(tiles.lights[k]);
        points.push_back(s.point);
        normals.push_back(s.normal);
      }
    }
}

Image shadeAllLights(const CameraHits& hits, const BundleQuery& query, int pcf) {
  return shadeEach(hits, query, pcf, [&](int, int, auto&& fn) {
    for (size_t i = 0; i < query.lightCount(); ++i) fn(i);
  });
}

}  // namespace cpvs
