#include "cpvs/query/light_tiles.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "cpvs/base/error.h"

namespace cpvs {

LightTiles cullLights(const BundleQuery& query, const std::vector<Vec3>& points, const std::vector<uint8_t>& hit,
                      int width, int height, int tileSize, uint32_t capacity) {
  if (tileSize < 1 || tileSize > 256) throw InputError("light tiles: tile size " + std::to_string(tileSize) + " is outside [1, 256]");
  if (width < 1 || height < 1 || points.size() != size_t(width) * size_t(height) || hit.size() != points.size())
    throw InputError("light tiles: " + std::to_string(points.size()) + " points for a " + std::to_string(width) + "x" +
                     std::to_string(height) + " image");
  LightTiles t;
  t.tileSize = tileSize;
  t.capacity = capacity;
  t.tilesX = (width + tileSize - 1) / tileSize;
  t.tilesY = (height + tileSize - 1) / tileSize;
  const size_t tiles = size_t(t.tilesX) * size_t(t.tilesY);
  std::vector<double> reach(query.lightCount());
  for (size_t i = 0; i < reach.size(); ++i) reach[i] = query.reach(i);
  std::vector<std::vector<uint32_t>> lists(tiles);
  tbb::parallel_for(size_t(0), tiles, [&](size_t k) {
    const int tx = int(k % size_t(t.tilesX)), ty = int(k / size_t(t.tilesX));
    const double inf = std::numeric_limits<double>::infinity();
    Vec3 lo{inf, inf, inf}, hi{-inf, -inf, -inf};
    for (int y = ty * tileSize; y < std::min(height, (ty + 1) * tileSize); ++y)
      for (int x = tx * tileSize; x < std::min(width, (tx + 1) * tileSize); ++x) {
        const size_t i = size_t(y) * size_t(width) + size_t(x);
        if (!hit[i]) continue;
        const Vec3& p = points[i];
        lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
        hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
      }
    if (!(lo.x <= hi.x)) return;  // only sky
    for (size_t i = 0; i < reach.size(); ++i) {
      // The distance from the light to the box against the light's reach.
      const Vec3& c = query.light(i).light.position;
      const double dx = std::max({lo.x - c.x, 0.0, c.x - hi.x}), dy = std::max({lo.y - c.y, 0.0, c.y - hi.y}),
                   dz = std::max({lo.z - c.z, 0.0, c.z - hi.z});
      if (dx * dx + dy * dy + dz * dz <= reach[i] * reach[i]) lists[k].push_back(uint32_t(i));
    }
  });
  t.begin.assign(tiles + 1, 0);
  for (size_t k = 0; k < tiles; ++k) {
    t.begin[k + 1] = t.begin[k] + uint32_t(lists[k].size());
    t.overflowing += lists[k].size() > capacity;
    t.longest = std::max(t.longest, uint32_t(lists[k].size()));
  }
  t.lights.reserve(t.begin[tiles]);
  for (const auto& l : lists) t.lights.insert(t.lights.end(), l.begin(), l.end());
  return t;
}

}  // namespace cpvs
