#include "cpvs/bake/raster_scene.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "cpvs/base/error.h"
#include "cpvs/light/frustum_clip.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

namespace {

// A projected vertex: texel-space position and depth along the light from the near plane.
struct Projected {
  double x, y;
};

// Sub-texel bits: never more than this (2^-25 texel is far below the error of any
// double-precision ray test at the same texel), never fewer than the edge range allows.
constexpr int kMaxSubBits = 25;
// Edge function values in a partially covered 8x8 block stay below 14 * 2^(k + 2 S) for
// edges up to 2^k texels long; 2^63 bounds them when k + 2 S <= 59.
constexpr int kEdgeBudget = 59;

int64_t floorDiv(int64_t a, int64_t b) { return a / b - ((a % b != 0) && ((a < 0) != (b < 0))); }

// Sutherland-Hodgman against one side of the guard box. The crossing of an edge is
// computed from its endpoints in a fixed order, so the two triangles sharing an edge get
// bit-identical crossings and stay watertight after snapping.
template <class Inside, class Cross>
void clipAgainst(std::vector<Projected>& poly, Inside inside, Cross cross) {
  std::vector<Projected> out;
  for (size_t i = 0; i < poly.size(); ++i) {
    const Projected a = poly[i], b = poly[(i + 1) % poly.size()];
    const bool ia = inside(a), ib = inside(b);
    if (ia) out.push_back(a);
    if (ia != ib) {
      const bool ordered = a.x < b.x || (a.x == b.x && a.y < b.y);
      out.push_back(ordered ? cross(a, b) : cross(b, a));
    }
  }
  poly = std::move(out);
}

std::vector<Projected> clipToBox(const std::array<Projected, 3>& tri, double lo, double hi) {
  std::vector<Projected> poly(tri.begin(), tri.end());
  auto atX = [](double x) {
    return [x](Projected a, Projected b) { return Projected{x, a.y + (b.y - a.y) * ((x - a.x) / (b.x - a.x))}; };
  };
  auto atY = [](double y) {
    return [y](Projected a, Projected b) { return Projected{a.x + (b.x - a.x) * ((y - a.y) / (b.y - a.y)), y}; };
  };
  clipAgainst(poly, [lo](Projected p) { return p.x >= lo; }, atX(lo));
  if (!poly.empty()) clipAgainst(poly, [hi](Projected p) { return p.x <= hi; }, atX(hi));
  if (!poly.empty()) clipAgainst(poly, [lo](Projected p) { return p.y >= lo; }, atY(lo));
  if (!poly.empty()) clipAgainst(poly, [hi](Projected p) { return p.y <= hi; }, atY(hi));
  return poly;
}

// A triangle's depth plane over texel space, before snapping.
struct Plane {
  double ax, ay, at, gx, gy, tMin, tMax;
};

// A triangle (or a piece of a clipped one) waiting for the scene's sub-texel bits.
struct Piece {
  std::array<Projected, 3> v;
  uint32_t plane;
};

// Lists items per cell of 2^12 texels (or the whole grid): `bounds(i, b)` gives item i's
// inclusive texel bounds {x0, y0, x1, y1} inside the grid, empty when x0 > x1.
template <class Bounds>
void buildCellIndex(RasterScene::CellIndex& index, int log2R, size_t count, Bounds&& bounds) {
  index.log2Cell = std::min(log2R, kDefaultLog2TileSize);
  index.perSide = (uint64_t(1) << log2R) >> index.log2Cell;
  const size_t cells = size_t(index.perSide * index.perSide);
  index.begin.assign(cells + 1, 0);
  auto forCells = [&](size_t i, auto&& fn) {
    int64_t b[4];
    bounds(i, b);
    if (b[0] > b[2] || b[1] > b[3]) return;
    for (int64_t cy = b[1] >> index.log2Cell; cy <= b[3] >> index.log2Cell; ++cy)
      for (int64_t cx = b[0] >> index.log2Cell; cx <= b[2] >> index.log2Cell; ++cx) fn(size_t(cy) * index.perSide + size_t(cx));
  };
  for (size_t i = 0; i < count; ++i) forCells(i, [&](size_t c) { ++index.begin[c + 1]; });
  for (size_t c = 0; c < cells; ++c) index.begin[c + 1] += index.begin[c];
  index.items.resize(index.begin[cells]);
  std::vector<uint32_t> fill(index.begin.begin(), index.begin.end() - 1);
  for (size_t i = 0; i < count; ++i) forCells(i, [&](size_t c) { index.items[fill[c]++] = uint32_t(i); });
}

}  // namespace

// Every projected triangle of a scene, before the scene's sub-texel bits are known.
struct RasterScene::Projection {
  std::vector<Plane> planes;
  std::vector<Piece> pieces;
  std::vector<uint32_t> planeTriangle;
  std::vector<uint8_t> planeFront;
  double longest = 1;  // the longest piece edge along x or y, texels

  // Adds a triangle's plane and its pieces: the fan of a convex polygon in texel space.
  void add(const Plane& plane, uint32_t triangle, bool front, const std::vector<Projected>& poly) {
    const uint32_t planeIndex = uint32_t(planes.size());
    planes.push_back(plane);
    planeTriangle.push_back(triangle);
    planeFront.push_back(front ? 1 : 0);
    for (size_t i = 1; i + 1 < poly.size(); ++i) pieces.push_back({{poly[0], poly[i], poly[i + 1]}, planeIndex});
    for (size_t a = 0; a < poly.size(); ++a)
      for (size_t b = a + 1; b < poly.size(); ++b)
        longest = std::max({longest, std::abs(poly[a].x - poly[b].x), std::abs(poly[a].y - poly[b].y)});
  }
};

RasterScene::RasterScene(const Scene& scene, const OrthoGrid& grid)
    : grid_(grid), log2Resolution_(grid.log2Resolution), tieDistance_(grid.sceneDepthExtent() * 1e-6) {
  const double R = double(grid.resolution());
  const double toTexel = R / grid.extent;
  depthLimit_ = grid.depthExtent * 1.0001;  // as TexelMapping's far end
  // Far outside the grid a triangle is clipped: the guard box keeps every coordinate
  // (and so every edge) below 3 R texels.
  const double guardLo = -R, guardHi = 2 * R;

  Projection projection;
  for (size_t t = 0; t < scene.triangleCount(); ++t) {
    std::array<Vec3, 3> rel;
    std::array<Projected, 3> p;
    std::array<double, 3> depth;
    for (int c = 0; c < 3; ++c) {
      rel[size_t(c)] = scene.vertex(t, c) - grid.origin;
      p[size_t(c)] = {(dot(rel[size_t(c)], grid.frame.u) - grid.u0) * toTexel,
                      (dot(rel[size_t(c)], grid.frame.v) - grid.v0) * toTexel};
      depth[size_t(c)] = dot(rel[size_t(c)], grid.frame.dir) - grid.d0;
    }
    Outline outline;
    for (int c = 0; c < 3; ++c) {
      outline.x[c] = p[size_t(c)].x;
      outline.y[c] = p[size_t(c)].y;
    }
    outlines_.push_back(outline);
    const double e1x = p[1].x - p[0].x, e1y = p[1].y - p[0].y, e2x = p[2].x - p[0].x, e2y = p[2].y - p[0].y;
    const double det = e1x * e2y - e2x * e1y;
    if (!(std::abs(det) > 0) || !std::isfinite(det)) continue;  // edge-on to the light
    const double d1 = depth[1] - depth[0], d2 = depth[2] - depth[0];
    Plane plane{p[0].x, p[0].y, depth[0], (d1 * e2y - d2 * e1y) / det, (e1x * d2 - e2x * d1) / det,
                std::min({depth[0], depth[1], depth[2]}), std::max({depth[0], depth[1], depth[2]})};
    if (!std::isfinite(plane.gx) || !std::isfinite(plane.gy)) continue;
    // Front as a ray tracer decides it: the geometric normal against the ray.
    const bool front = dot(cross(rel[1] - rel[0], rel[2] - rel[0]), grid.frame.dir) < 0;
    bool inGuard = true;
    for (const Projected& q : p) inGuard = inGuard && q.x >= guardLo && q.x <= guardHi && q.y >= guardLo && q.y <= guardHi;
    projection.add(plane, uint32_t(t), front,
                   inGuard ? std::vector<Projected>(p.begin(), p.end()) : clipToBox(p, guardLo, guardHi));
  }
  snap(scene, projection);
}

RasterScene::RasterScene(const Scene& scene, const PerspectiveGrid& grid, double tanCone)
    : spot_(grid), tanCone_(tanCone), log2Resolution_(grid.log2Resolution()), tieDistance_(grid.far() * 1e-6) {
  if (!(tanCone > 0) || !std::isfinite(tanCone)) throw InputError("spot light: the cone must be wider than 0 degrees");
  const double half = double(grid.resolution()) * 0.5, t = grid.tanHalfFov();
  const double scale = half / t;  // texels per unit of the image plane at unit depth
  depthLimit_ = grid.far() * 1.0001;  // as texelRay's tMax
  const LightFrame& f = grid.frame();
  // In the light's frame a triangle is clipped against the plane a hair in front of the
  // light (nothing behind it reaches the grid; what lies between the hair and the light
  // is lost, as for a ray that starts there) and the guard frustum |a|, |b| <= 3 t z,
  // whose image is the guard box [-R, 2R]^2 of the directional light's rasterizer.
  const double zClip = grid.near() * 0x1p-20, guard = 3 * t;

  Projection projection;
  std::vector<LightPoint> poly, scratch;
  std::vector<Projected> image;
  for (size_t i = 0; i < scene.triangleCount(); ++i) {
    std::array<Vec3, 3> rel;
    poly.clear();
    for (int c = 0; c < 3; ++c) {
      rel[size_t(c)] = scene.vertex(i, c) - grid.position();
      poly.push_back({dot(rel[size_t(c)], f.u), dot(rel[size_t(c)], f.v), dot(rel[size_t(c)], f.dir)});
    }
    clipToFrustum(poly, scratch, zClip, guard);
    if (poly.size() < 3) continue;  // nothing of it in front of the light, near the grid
    image.clear();
    double zMin = poly[0].z, zMax = poly[0].z;
    for (const LightPoint& q : poly) {
      image.push_back({q.a / q.z * scale + half, q.b / q.z * scale + half});
      zMin = std::min(zMin, q.z);
      zMax = std::max(zMax, q.z);
    }
    for (size_t j = 1; j + 1 < image.size(); ++j)
      outlines_.push_back({{image[0].x, image[j].x, image[j + 1].x}, {image[0].y, image[j].y, image[j + 1].y}});
    // The ray through texel-space (x, y) runs along dir + u A(x) + v B(y), A(x) = (x / half
    // - 1) t, and meets the plane n . (p - v0) = 0 at depth (n . r0) / (n . ray): its
    // inverse is affine in (x, y).
    const Vec3 n = cross(rel[1] - rel[0], rel[2] - rel[0]);
    const double nr = dot(n, rel[0]);
    if (!(std::abs(nr) > 0) || !std::isfinite(nr)) continue;  // the plane holds the light: edge-on
    const double nu = dot(n, f.u) / nr, nv = dot(n, f.v) / nr, nd = dot(n, f.dir) / nr;
    const double ax = image[0].x, ay = image[0].y;
    Plane plane{ax, ay, nd + (ax / half - 1) * t * nu + (ay / half - 1) * t * nv, t / half * nu, t / half * nv, zMin, zMax};
    if (!std::isfinite(plane.at) || !std::isfinite(plane.gx) || !std::isfinite(plane.gy)) continue;
    // Front as a ray tracer decides it: the geometric normal against the ray from the light.
    projection.add(plane, uint32_t(i), nr < 0, image);
  }
  snap(scene, projection);
}

const OrthoGrid& RasterScene::grid() const {
  CPVS_CHECK(!spot_);
  return grid_;
}

void RasterScene::snap(const Scene& scene, const Projection& projection) {
  // The finest snapping whose edge functions still fit: edges up to 2^k texels (k
  // counts the snapping's own half unit).
  const int k = int(std::ceil(std::log2(projection.longest + 1)));
  subBits_ = std::min(kMaxSubBits, (kEdgeBudget - k) / 2);
  CPVS_CHECK(subBits_ >= 8);
  const double scale = std::ldexp(1.0, subBits_);
  const int64_t one = int64_t(1) << subBits_, half = one / 2;
  const int64_t lastTexel = int64_t(resolution()) - 1;

  triangles_.reserve(projection.pieces.size());
  for (const Piece& piece : projection.pieces) {
    RasterTriangle r{};
    for (int c = 0; c < 3; ++c) {
      r.fx[c] = std::llround(piece.v[size_t(c)].x * scale);
      r.fy[c] = std::llround(piece.v[size_t(c)].y * scale);
    }
    const __int128 area = __int128(r.fx[1] - r.fx[0]) * (r.fy[2] - r.fy[0]) - __int128(r.fx[2] - r.fx[0]) * (r.fy[1] - r.fy[0]);
    if (area == 0) continue;
    if (area < 0) {
      std::swap(r.fx[1], r.fx[2]);
      std::swap(r.fy[1], r.fy[2]);
    }
    for (int e = 0; e < 3; ++e) {
      const int64_t dx = r.fx[(e + 1) % 3] - r.fx[e], dy = r.fy[(e + 1) % 3] - r.fy[e];
      // Of an edge's two directions exactly one owns the centres lying on it.
      r.bias[e] = (dy < 0 || (dy == 0 && dx > 0)) ? 1 : 0;
    }
    const int64_t minX = std::min({r.fx[0], r.fx[1], r.fx[2]}), maxX = std::max({r.fx[0], r.fx[1], r.fx[2]});
    const int64_t minY = std::min({r.fy[0], r.fy[1], r.fy[2]}), maxY = std::max({r.fy[0], r.fy[1], r.fy[2]});
    // Texels whose centre (x * one + half) lies within the snapped bounds.
    r.xMin = std::max<int64_t>(0, floorDiv(minX - half + one - 1, one));
    r.xMax = std::min<int64_t>(lastTexel, floorDiv(maxX - half, one));
    r.yMin = std::max<int64_t>(0, floorDiv(minY - half + one - 1, one));
    r.yMax = std::min<int64_t>(lastTexel, floorDiv(maxY - half, one));
    if (r.xMin > r.xMax || r.yMin > r.yMax) continue;
    const Plane& pl = projection.planes[piece.plane];
    r.ax = pl.ax;
    r.ay = pl.ay;
    r.at = pl.at;
    r.gx = pl.gx;
    r.gy = pl.gy;
    r.tMin = pl.tMin;
    r.tMax = pl.tMax;
    r.triangle = projection.planeTriangle[piece.plane];
    r.front = projection.planeFront[piece.plane] != 0;
    r.closed = r.triangle < scene.closed.size() && scene.closed[r.triangle] != 0;
    triangles_.push_back(r);
  }

  const uint64_t R64 = resolution();
  buildCellIndex(rasterCells_, log2Resolution_, triangles_.size(), [&](size_t i, int64_t (&b)[4]) {
    const RasterTriangle& r = triangles_[i];
    b[0] = r.xMin, b[1] = r.yMin, b[2] = r.xMax, b[3] = r.yMax;
  });
  // Outlines by their bounds padded by a texel, for the conservative test.
  buildCellIndex(outlineCells_, log2Resolution_, outlines_.size(), [&](size_t i, int64_t (&b)[4]) {
    const Outline& o = outlines_[i];
    const double x0 = std::floor(std::min({o.x[0], o.x[1], o.x[2]})) - 1, x1 = std::ceil(std::max({o.x[0], o.x[1], o.x[2]})) + 1;
    const double y0 = std::floor(std::min({o.y[0], o.y[1], o.y[2]})) - 1, y1 = std::ceil(std::max({o.y[0], o.y[1], o.y[2]})) + 1;
    const double last = double(R64 - 1);
    if (!(x1 >= 0 && y1 >= 0 && x0 <= last && y0 <= last)) {  // outside, or not finite
      b[0] = b[1] = 1, b[2] = b[3] = 0;
      return;
    }
    b[0] = int64_t(std::max(0.0, x0)), b[1] = int64_t(std::max(0.0, y0));
    b[2] = int64_t(std::min(last, x1)), b[3] = int64_t(std::min(last, y1));
  });
}

template <class Fn>
void RasterScene::CellIndex::forEach(uint64_t x0, uint64_t y0, uint64_t x1, uint64_t y1, Fn&& fn) const {
  for (uint64_t cy = y0 >> log2Cell; cy <= y1 >> log2Cell; ++cy)
    for (uint64_t cx = x0 >> log2Cell; cx <= x1 >> log2Cell; ++cx) {
      const size_t c = size_t(cy * perSide + cx);
      for (uint32_t i = begin[c]; i < begin[c + 1]; ++i) fn(items[i]);
    }
}

void RasterScene::trianglesTouching(uint64_t x0, uint64_t y0, uint64_t width, uint64_t height,
                                    std::vector<uint32_t>& out) const {
  out.clear();
  const uint64_t R = resolution();
  if (width == 0 || height == 0 || x0 >= R || y0 >= R) return;
  const uint64_t x1 = std::min(R, x0 + width) - 1, y1 = std::min(R, y0 + height) - 1;
  rasterCells_.forEach(x0, y0, x1, y1, [&](uint32_t i) {
    const RasterTriangle& r = triangles_[i];
    if (uint64_t(r.xMax) >= x0 && uint64_t(r.xMin) <= x1 && uint64_t(r.yMax) >= y0 && uint64_t(r.yMin) <= y1)
      out.push_back(i);
  });
  if ((x0 >> rasterCells_.log2Cell) != (x1 >> rasterCells_.log2Cell) ||
      (y0 >> rasterCells_.log2Cell) != (y1 >> rasterCells_.log2Cell)) {
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
  }
}

bool RasterScene::covers(uint32_t i, uint64_t x, uint64_t y) const {
  const RasterTriangle& r = triangles_[i];
  const int64_t one = int64_t(1) << subBits_;
  const int64_t px = int64_t(x) * one + one / 2, py = int64_t(y) * one + one / 2;
  for (int e = 0; e < 3; ++e) {
    const int f = (e + 1) % 3;
    const __int128 edge = __int128(r.fx[f] - r.fx[e]) * (py - r.fy[e]) - __int128(r.fy[f] - r.fy[e]) * (px - r.fx[e]);
    if (edge + r.bias[e] <= 0) return false;
  }
  return true;
}

bool RasterScene::touchesRectangle(uint64_t x0, uint64_t y0, uint64_t width, uint64_t height) const {
  const uint64_t R = resolution();
  if (width == 0 || height == 0 || x0 >= R || y0 >= R) return false;
  const uint64_t x1 = std::min(R, x0 + width) - 1, y1 = std::min(R, y0 + height) - 1;
  // Outside a spot light's cone every voxel is undefined, which the undefined rules
  // resolve to lit (no transition).
  if (spot_ && spot_->coneMissesTexels(x0, y0, x1 - x0 + 1, y1 - y0 + 1, tanCone_)) return false;
  // The centres of the rectangle's texels, padded by one texel (a ray tracer's rounding).
  const double rx0 = double(x0) - 0.5, ry0 = double(y0) - 0.5, rx1 = double(x1) + 1.5, ry1 = double(y1) + 1.5;
  bool touched = false;
  outlineCells_.forEach(x0, y0, x1, y1, [&](uint32_t i) {
    if (touched) return;
    const Outline& o = outlines_[i];
    if (std::max({o.x[0], o.x[1], o.x[2]}) < rx0 || std::min({o.x[0], o.x[1], o.x[2]}) > rx1 ||
        std::max({o.y[0], o.y[1], o.y[2]}) < ry0 || std::min({o.y[0], o.y[1], o.y[2]}) > ry1)
      return;
    for (int e = 0; e < 3; ++e) {
      const int f = (e + 1) % 3, g = (e + 2) % 3;
      const double dx = o.x[f] - o.x[e], dy = o.y[f] - o.y[e];
      auto side = [&](double x, double y) { return dx * (y - o.y[e]) - dy * (x - o.x[e]); };
      // The edge separates when the opposite vertex and every corner are on strictly
      // opposite sides (a degenerate triangle is never separated this way).
      const double inside = side(o.x[g], o.y[g]);
      if (inside == 0) continue;
      bool allOutside = true;
      for (double cx : {rx0, rx1})
        for (double cy : {ry0, ry1}) allOutside = allOutside && side(cx, cy) * inside < 0;
      if (allOutside) return;
    }
    touched = true;
  });
  return touched;
}

}  // namespace cpvs
