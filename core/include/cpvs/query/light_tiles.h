// Tiled light culling (seed 000 §6.2): which of a bundle's lights can reach the points a
// tile of the screen sees, so that shading a pixel visits those lights only.
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/base/vec3.h"
#include "cpvs/query/bundle_query.h"

namespace cpvs {

/// Per screen tile of tileSize x tileSize pixels, the lights whose reach (BundleQuery::
/// reach) meets the bounding box of the tile's points, in increasing index. Conservative:
/// a light left out of a tile answers exactly 0 at every point of it. `capacity` is the
/// list length a fixed-size list (a GPU's) would hold: tiles over it are counted, never
/// cut.
struct LightTiles {
  int tileSize = 16, tilesX = 0, tilesY = 0;
  uint32_t capacity = 0;
  std::vector<uint32_t> begin;   // tilesX * tilesY + 1, into lights
  std::vector<uint32_t> lights;
  uint64_t overflowing = 0;      // tiles with more than capacity lights
  uint32_t longest = 0;          // the longest list

  size_t tile(int px, int py) const { return size_t(py / tileSize) * size_t(tilesX) + size_t(px / tileSize); }
};

/// Culls the bundle's lights over a width x height image whose pixel i sees points[i]
/// (hit[i] false: nothing, sky). Multithreaded over tiles. InputError for a tile size
/// outside [1, 256] or sizes that do not match.
LightTiles cullLights(const BundleQuery& query, const std::vector<Vec3>& points, const std::vector<uint8_t>& hit,
                      int width, int height, int tileSize = 16, uint32_t capacity = 64);

}  // namespace cpvs
