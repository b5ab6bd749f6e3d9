// Where receivers can be, and which voxels their lookups read (seed 004): along a texel's
// column the transition from lit to shadowed may lie anywhere between the last voxel a
// receiver's lookup needs lit and the first one it needs shadowed.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/bake/texel_slices.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/light/perspective_grid.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

/// Steepest walkable surface a ground layer covers by default, in degrees from level.
constexpr double kDefaultGroundSlopeDeg = 45;

/// The sides sampled cameras see, for one scene and declaration (their hashes).
struct CameraViewsCache {
  std::mutex mutex;
  Hash128 scene, declaration;
  std::vector<uint8_t> sides;
};

/// What a bake is declared for: who receives (options.h), the widest PCF filter their
/// lookups use; for ReceiverKind::Volume (and optionally Cameras) the volume in which
/// dynamic receivers move: closed meshes in world space (boxes: appendBox) and a ground
/// layer (where characters and vehicles are: every point from groundLayerFrom up to
/// groundLayer scene units above a walkable surface, see walkable()); for Cameras where
/// cameras can be (boxes, points, polyline paths), how far they see and how the sides they
/// see are found (camera_views.h).
struct ReceiverDeclaration {
  ReceiverKind kind = ReceiverKind::Everywhere;
  int maxPcf = kMaxPcfWidthOption;
  Scene volume;
  double groundLayer = 0;  // 0: no layer
  double groundLayerFrom = 0;
  double groundSlopeDeg = kDefaultGroundSlopeDeg;
  std::vector<std::pair<Vec3, Vec3>> cameraRegions;  // (min, max)
  std::vector<Vec3> cameraPoints;
  std::vector<std::vector<Vec3>> cameraPaths;
  double viewDistance = 0;
  CameraVisibility cameraVisibility = CameraVisibility::Faced;
  double cameraSpacing = 0;  // Sampled: positions this far apart; 0: the default (camera_views.h cameraSpacing)
  uint32_t cameraRays = 0;   // Sampled: rays per side of a cube face; 0: kDefaultCameraRays
  // Sampled: the sides seen, cast once per scene and declaration and shared by copies
  // (receivingSides keys it by both hashes).
  std::shared_ptr<CameraViewsCache> seen = std::make_shared<CameraViewsCache>();
};

/// Which sides of each scene triangle receive under the declaration: bit 0 the front (the
/// side its winding faces), bit 1 the back. Surfaces and Volume: the front; Everywhere and
/// SurfacesTwoSided: both for open triangles; Cameras, faced: each side of a triangle whose
/// bounding box lies within the view distance of a camera place (a region, a point, a
/// path's segment's box: boxes compared, a conservative test) that some point of that place
/// faces; Cameras, sampled: the sides camera rays hit (sampleCameraViews). Closed parts
/// receive on the outside only. What the bake frees by and `verify` samples.
std::vector<uint8_t> receivingSides(const Scene& scene, const ReceiverDeclaration& declaration);

/// Whether scene triangle t carries the declaration's ground layer: a layer is declared
/// and the triangle's front side faces up (+y) within groundSlopeDeg of level ground.
bool walkable(const Scene& scene, const ReceiverDeclaration& declaration, size_t t);

/// InputError unless the declaration is usable: an odd PCF width in [1, 9]; a volume
/// (closed) for ReceiverKind::Volume, none but for Volume and Cameras; camera regions
/// (finite, min < max), points and paths (finite, a path of one point or more), a positive
/// view distance and, when sampled, a spacing >= 0 and rays up to kMaxCameraRays exactly
/// for Cameras; a ground layer
/// (finite, 0 <= from < height; a slope in [0, 90)) only for Volume and Cameras.
void checkReceiverDeclaration(const ReceiverDeclaration& declaration);

/// Content hash of what the declaration lets a bake leave free: the kind, the PCF width,
/// the volume's geometry, the camera regions and view distance, the ground layer. Zero for
/// Everywhere (nothing declared).
Hash128 receiverHash(const ReceiverDeclaration& declaration);

/// The reads of every declared receiver, projected onto one grid. Each receiver triangle
/// (a surface's side, or a volume's boundary) becomes a region of texel columns and, per
/// column, a conservative range of slices that its lookups may read: the lookup point is
/// the receiver's point moved by the normal offset of any PCF width up to maxPcf (along
/// the side's geometric normal for surfaces, in any direction for volumes, with the 1/256
/// the offset may exceed), read at that slice over the filter's footprint. A volume part's
/// reads at a column are the hull of its boundary's: they cover its interior too. A
/// walkable triangle's ground layer is one prism, swept from the triangle raised by the
/// layer's bottom to the triangle raised by its top: its reads at a column are one range.
/// Built once per bake and shared read-only.
class ReceiverSet {
 public:
  /// InputError for an invalid declaration. Everywhere gives an empty set that frees
  /// nothing (freeIntervals leaves slices as they are).
  ReceiverSet(const Scene& scene, const OrthoGrid& grid, const ReceiverDeclaration& declaration);
  /// The same reads on a spot grid (a spot light's, or a face of a point light's cube),
  /// where a plane is not a plane in voxels: each receiver triangle is clipped to the view
  /// depths whose lookups can reach a slice, and at each column the view depths of its
  /// points that a lookup there can come from are bounded by 1 / zv, which is affine in
  /// texel coordinates across a plane (its range over the column's window, cut to the
  /// triangle's); their voxel z (PerspectiveGrid::voxelZ) widened by the normal offset is
  /// the column's read range. A surface side facing the light reads towards it, one facing
  /// away behind it. Volume parts are hulled per column as on the sun's grid; a ground
  /// layer is one closed prism per walkable triangle, hulled alike.
  ReceiverSet(const Scene& scene, const PerspectiveGrid& grid, const ReceiverDeclaration& declaration);
  /// Every point of an R^3 grid (of any light kind) receives: nothing is freed.
  static ReceiverSet everywhere(uint64_t resolution);

  ReceiverKind kind() const { return kind_; }
  int maxPcf() const { return maxPcf_; }

  /// False when no receiver's lookup reads a voxel of the texel rectangle: every voxel of
  /// it is free, which the undefined rules resolve to all lit. Always true for Everywhere.
  bool touchesRectangle(uint64_t x0, uint64_t y0, uint64_t width, uint64_t height) const;

  /// How many texel columns of the grid some receiver's lookups may reach (their
  /// coverage, before any depth is known); R² for Everywhere.
  uint64_t columnsReached() const;
  /// Those columns, R² flags row by row (all 1 for Everywhere).
  std::vector<uint8_t> reachedColumns() const;

  /// Widens the classification of the texels [x0, x0 + width) x [y0, y0 + height) (row
  /// major, as rendered) to what the receivers need: firstUndefined becomes one past the
  /// last slice a lookup needs lit (0: none), firstShadowed the first slice a lookup needs
  /// shadowed (R: none). Slices a lookup reads inside the old undefined range stay free.
  /// Then each 8x8 column whose texels' ranges share a slice is given one transition at
  /// the most aligned such slice (`shareColumns`; false leaves every texel's range as its
  /// reads make it: what a bound on the free voxels measures). Multithreaded; depends only
  /// on each texel's own position and its 8x8 column.
  void freeIntervals(uint64_t x0, uint64_t y0, uint32_t width, uint32_t height, TexelSlices& slices,
                     bool shareColumns = true) const;

  /// Rings a span may have: a surface's lookups are bounded per pair of filter widths
  /// (1-3, 5-7, 9).
  static constexpr int kMaxRings = (kMaxPcfWidthOption + 3) / 4;

  /// Where one group of lookups of a receiver triangle lands (a surface's lookups of a
  /// pair of filter widths; all of a volume's): the columns they reach and, at each, the read
  /// depths relative to the triangle's plane.
  struct Ring {
    double support[8];                 // column centres c with dir . c <= support
    int64_t xMin, yMin, xMax, yMax;    // columns reached (inclusive, inside the grid)
    double loOff, hiOff;               // read depths relative to the plane at a column's centre
  };
  /// A receiver triangle: where its lookups land, in voxel coordinates.
  struct Span {
    double px, py, pz;            // plane anchor (voxels) ...
    double gx, gy;                // ... and slope: the triangle's depth plane, unless !planar (too thin)
    double zLo, zHi;              // the bounds of every read depth
    double dirX[8], dirY[8];      // the rings' half-plane directions (the first `dirs` are not zero) ...
    double invDirX[8];            // ... and 1 / dirX (0 where dirX is 0)
    uint32_t dirs;
    int64_t xMin, yMin, xMax, yMax;  // columns some ring reaches (their bounds' union)
    Ring ring[kMaxRings];
    uint32_t rings;
    uint32_t part;                // 0: a surface; k > 0: the k-th volume part (hulled)
    bool planar;
  };
  /// A receiver triangle on a spot grid (a volume's or a prism's boundary triangle, hulled
  /// by `part`), in texel coordinates.
  struct FrustumSpan {
    int64_t xMin, yMin, xMax, yMax;  // columns its lookups reach (inclusive, inside the grid)
    double wx, wy, w0;               // 1 / zv = w0 + wx x + wy y on its plane, when planar
    double slack;                    // on that: above its rounding anywhere in the grid
    double wLo, wHi;                 // 1 / zv over the triangle clipped to the depths read
    double window;                   // a column x is read from points of texel x in [x - window, x + 1 + window)
    double zLoOff, zHiOff;           // reads' voxel z relative to the point's own
    uint32_t part;                   // 0: a surface; k > 0: the k-th closed part (hulled)
    bool planar;
  };

 private:
  ReceiverSet() = default;
  static bool columnRange(const Span& s, const Ring& r, int64_t y, int64_t& x0, int64_t& x1);
  /// What span s reads at column (x, y): kReads and the slices [a, b], or why none. Along
  /// a row the answer is monotone (the read range moves one way, and each kind of none
  /// holds at one end only), so a run whose ends agree answers alike in between.
  enum FrustumRead : int { kReads = 0, kNoneBefore = 1, kNoneAfter = 2 };
  /// `hints`: the slices of the last call's depths (PerspectiveGrid::voxelZ), updated.
  FrustumRead frustumReads(const FrustumSpan& s, int64_t x, int64_t y, uint32_t& a, uint32_t& b, uint32_t* hints) const;
  /// fn(x, a, b) for each column of [xa, xb] in row y that span s reads: exactly the
  /// columns and slices of frustumReads, evaluated at the ends of aligned runs only where
  /// they agree.
  template <class Fn>
  void forFrustumRow(const FrustumSpan& s, int64_t y, int64_t xa, int64_t xb, Fn&& fn) const;
  /// Lists every span per cell of 2^log2Cell_ texels by its column bounds.
  template <class S>
  void indexCells(const std::vector<S>& spans, int log2Resolution);
  ReceiverKind kind_ = ReceiverKind::Everywhere;
  int maxPcf_ = kMaxPcfWidthOption;
  uint32_t R_ = 0;
  std::vector<Span> spans_;
  std::optional<PerspectiveGrid> spot_;     // a spot grid: its spans are frustumSpans_
  std::vector<FrustumSpan> frustumSpans_;
  // Spans listed per cell of 2^log2Cell texels, by their column bounds.
  int log2Cell_ = 0;
  uint64_t cellsPerSide_ = 0;
  std::vector<uint32_t> cellBegin_, cellItems_;
};

}  // namespace cpvs
