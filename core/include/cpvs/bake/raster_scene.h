// A scene projected onto one light grid for exact rasterization: every triangle's
// vertices in texel space, snapped to fixed point, with its integer edge functions and
// its depth plane. What the rasterizer (raster_slices.h) and the empty-tile test read.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/light/perspective_grid.h"

namespace cpvs {

struct Scene;

/// One projected triangle, counter-clockwise in snapped texel space. A texel centre
/// (x + 0.5, y + 0.5) is covered when every edge function, plus its tie bias, is > 0:
/// the bias (1 on owning edges, 0 on the others) is the top-left rule that gives a centre
/// on an edge shared by two triangles to exactly one of them.
struct RasterTriangle {
  int64_t fx[3], fy[3];            // snapped vertices, 2^subBits units per texel
  int64_t bias[3];                 // edge e runs from vertex e to vertex (e + 1) % 3
  int64_t xMin, xMax, yMin, yMax;  // texels whose centres may be covered (inclusive)
  double ax, ay, at;               // depth plane anchor: texel-space vertex and its depth
  double gx, gy;                   // depth per texel along x and y
  double tMin, tMax;               // the triangle's depth range (clamps the plane)
  // For a spot light the plane is of 1 / depth (affine in texel space under a perspective
  // projection): at, gx and gy are of 1 / zv, and the depth is 1 / plane.
  uint32_t triangle;               // index in the scene
  bool front;                      // the light sees the front side (Embree's rule)
  bool closed;                     // part of a closed solid (Scene::closed)
};

/// The triangles of a scene seen from a grid's light, ready to be rasterized, with an
/// index of which triangles touch which coarse cell of the grid. Built once per bake and
/// shared read-only by every tile and thread.
///
/// Projection is in double relative to the grid; vertices are snapped to 2^-subBits()
/// texel, chosen per scene and grid so that every edge function evaluated in a partially
/// covered 8x8 block fits a 64-bit integer. Triangles reaching far outside the grid are
/// clipped to a guard band first; a triangle whose snapped area is zero (parallel to the
/// light) covers nothing, as for a ray that grazes it.
class RasterScene {
 public:
  RasterScene(const Scene& scene, const OrthoGrid& grid);
  /// The same for a spot light, perspective-correct: triangles are clipped in the light's
  /// frame (against the plane a hair in front of the light, nothing behind it reaching
  /// the grid, and the guard frustum) before they are projected, the depth plane is of
  /// 1 / zv, and a texel the cone of half-angle atan(tanCone) misses is all undefined (no
  /// light falls there). Geometry between the light and near lands in slice 0.
  RasterScene(const Scene& scene, const PerspectiveGrid& grid, double tanCone);

  /// The directional light's grid (only for a scene made with one).
  const OrthoGrid& grid() const;
  /// The spot light's grid, or null for a directional light.
  const PerspectiveGrid* spot() const { return spot_ ? &*spot_ : nullptr; }
  double tanCone() const { return tanCone_; }
  int log2Resolution() const { return log2Resolution_; }
  uint64_t resolution() const { return uint64_t(1) << log2Resolution_; }
  /// Crossings closer than this along a texel's ray are ties (orderCrossings): the same
  /// distance the ray tracer uses for the grid.
  double tieDistance() const { return tieDistance_; }
  int subBits() const { return subBits_; }
  const std::vector<RasterTriangle>& triangles() const { return triangles_; }
  /// Depth along a texel's ray beyond which nothing is hit (as for a ray tracer's tfar).
  double depthLimit() const { return depthLimit_; }

  /// The triangles (indices into triangles()) whose covered texels may lie in the texel
  /// rectangle [x0, x0 + width) x [y0, y0 + height), each once, in increasing order.
  void trianglesTouching(uint64_t x0, uint64_t y0, uint64_t width, uint64_t height,
                         std::vector<uint32_t>& out) const;

  /// Whether triangle i covers the centre of texel (x, y): the exact test one texel at a
  /// time, the reference the rasterizer's block kernel is checked against.
  bool covers(uint32_t i, uint64_t x, uint64_t y) const;

  /// False only when no triangle of the scene can be hit by a texel ray of the
  /// rectangle, by this rasterizer or by a ray tracer: a conservative test in double on
  /// every scene triangle as projected (bounding box, then its three edges against the
  /// rectangle of texel centres padded by a texel), so a false answer is certain. Such a
  /// tile renders to "no hit" everywhere and needs no rendering.
  bool touchesRectangle(uint64_t x0, uint64_t y0, uint64_t width, uint64_t height) const;

  /// Items (triangles) listed per coarse cell of the grid, by their texel bounds.
  struct CellIndex {
    int log2Cell = 0;
    uint64_t perSide = 0;
    std::vector<uint32_t> begin, items;
    /// Items whose bounds reach the inclusive texel rectangle, maybe more than once.
    template <class Fn>
    void forEach(uint64_t x0, uint64_t y0, uint64_t x1, uint64_t y1, Fn&& fn) const;
  };

 private:
  struct Outline {
    double x[3], y[3];
  };
  struct Projection;  // the projected triangles before snapping (raster_scene.cpp)
  // Snaps the projection's pieces to the finest sub-texel bits that fit and indexes them.
  void snap(const Scene& scene, const Projection& projection);

  OrthoGrid grid_;
  std::optional<PerspectiveGrid> spot_;
  double tanCone_ = 0;
  int log2Resolution_ = 0;
  double tieDistance_ = 0;
  int subBits_ = 0;
  double depthLimit_ = 0;
  std::vector<RasterTriangle> triangles_;
  std::vector<Outline> outlines_;  // every projected scene triangle, unsnapped
  CellIndex rasterCells_, outlineCells_;
};

}  // namespace cpvs
