// A scene made ready to bake on one grid: the renderer the options name, built once and
// shared read-only by every tile and thread.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>

#include "cpvs/bake/column_masks.h"
#include "cpvs/bake/options.h"
#include "cpvs/bake/raster_scene.h"
#include "cpvs/bake/receivers.h"
#include "cpvs/bake/stage_times.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

/// What a sun bake casts shadows with: the scene without its translucent meshes
/// (opaquePart, made in `storage`), or the scene itself when it has none. A plan of the
/// bake projects it, as BakeScene does.
const Scene& sunCasters(const Scene& scene, std::optional<Scene>& storage);

/// The scene projected for the rasterizer (always: it also answers which tiles nothing
/// touches), for the Embree renderer the BVH, and the declared receivers' reads.
/// `threads` caps Embree's builder (0: all cores). The sun's casters are the scene's
/// opaque part (opaquePart): its translucent meshes darken the light through a TOP tree
/// beside the CPVS instead (translucentTree), and still receive. A light's grid keeps
/// every mesh as a caster.
class BakeScene {
 public:
  BakeScene(const Scene& scene, const OrthoGrid& grid, Renderer renderer, int threads = 0,
            const ReceiverDeclaration& receivers = {});
  /// A spot light's grid, cut off by its cone of half-angle atan(tanCone): texels outside
  /// it are undefined. `scene` casts the shadows; the surfaces of `receiving` (null:
  /// `scene`) receive as `receivers` declares: a light's casters leave out its fixture,
  /// which still receives.
  BakeScene(const Scene& scene, const PerspectiveGrid& grid, double tanCone, Renderer renderer, int threads = 0,
            const ReceiverDeclaration& receivers = {}, const Scene* receiving = nullptr);
  ~BakeScene();
  BakeScene(const BakeScene&) = delete;
  BakeScene& operator=(const BakeScene&) = delete;

  /// The directional light's grid (only for a scene made with one).
  const OrthoGrid& grid() const { return raster_.grid(); }
  /// The spot light's grid, or null for a directional light.
  const PerspectiveGrid* spot() const { return raster_.spot(); }
  int log2Resolution() const { return raster_.log2Resolution(); }
  Renderer renderer() const { return renderer_; }
  const RasterScene& raster() const { return raster_; }

  const ReceiverSet& receivers() const { return receivers_; }
  /// False when no texel ray of the tile can hit anything (RasterScene::touchesRectangle,
  /// conservative for both renderers) or no declared receiver reads it: such a tile is
  /// all lit and needs no rendering.
  bool touchesTile(uint64_t tileX, uint64_t tileY, int log2TileSize) const;

  /// The column masks of the texels [x0, x0 + width) x [y0, y0 + height): rendered by the
  /// scene's renderer and resolved with `options`' rules (fused into the rasterizer's
  /// block loop; after the whole block for Embree). Declared receivers free what no
  /// lookup reads (ReceiverSet::freeIntervals) before the masks. Adds the time to
  /// "render", "receivers" and "masks" of `times` (the fused path counts it all as render).
  void columnMasks(const BakeOptions& options, uint64_t x0, uint64_t y0, uint32_t width, uint32_t height,
                   ColumnMasks& out, StageTimes& times) const;

 private:
  std::optional<Scene> opaque_;  // the sun's casters when some mesh is translucent (sunCasters)
  Renderer renderer_;
  ReceiverSet receivers_;  // before raster_: made beside it (bake_scene.cpp)
  RasterScene raster_;
  std::unique_ptr<RayScene> rays_;  // the Embree renderer only
};

}  // namespace cpvs
