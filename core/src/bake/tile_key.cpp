#include "cpvs/bake/tile_key.h"

#include <type_traits>
#include <vector>

#include "cpvs/bake/tile_plan.h"

namespace cpvs {

namespace {

/// Fields appended one by one, never a struct's bytes (padding is not data), then hashed.
struct KeyHasher {
  std::vector<uint8_t> bytes;
  template <class T>
  void add(const T& value) {
    static_assert(std::is_arithmetic_v<T>);
    const auto* p = reinterpret_cast<const uint8_t*>(&value);
    bytes.insert(bytes.end(), p, p + sizeof value);
  }
  void add(const Vec3& v) { add(v.x), add(v.y), add(v.z); }
  Hash128 finish() const { return contentHash(bytes.data(), bytes.size()); }
};

}  // namespace

std::optional<Hash128> tileKey(const BakeScene& scene, const BakeOptions& options, uint64_t tileX, uint64_t tileY) {
  if (scene.renderer() != Renderer::Raster || scene.spot() || scene.receivers().kind() != ReceiverKind::Everywhere ||
      options.compress == CompressMode::None)
    return std::nullopt;
  const RasterScene& raster = scene.raster();
  const OrthoGrid& g = scene.grid();
  KeyHasher h;
  h.add(uint32_t(1));  // the key's own version: a change to what decides a tile bumps it
  h.add(g.frame.dir), h.add(g.frame.u), h.add(g.frame.v), h.add(g.log2Resolution), h.add(g.origin);
  h.add(g.u0), h.add(g.v0), h.add(g.d0), h.add(g.extent), h.add(g.depthExtent), h.add(g.side());
  if (g.depthSlices != 0) h.add(g.depthSlices);  // the receivers' offsets (a cubic grid keeps its keys)
  h.add(uint8_t(options.closed)), h.add(uint8_t(options.exit)), h.add(options.cull), h.add(uint8_t(options.compress));
  h.add(uint8_t(options.undefinedRule)), h.add(options.log2TileSize), h.add(uint8_t(options.hash));
  h.add(uint8_t(options.renderer)), h.add(uint8_t(options.receivers)), h.add(options.receiverPcf);
  h.add(raster.subBits()), h.add(raster.tieDistance()), h.add(raster.depthLimit());
  h.add(tileX), h.add(tileY);
  const int t = TilePlan(g.log2Resolution, options.log2TileSize).log2TileSize();
  const uint64_t T = uint64_t(1) << t;
  std::vector<uint32_t> touching;
  raster.trianglesTouching(tileX * T, tileY * T, T, T, touching);
  h.add(uint64_t(touching.size()));
  // In scene order. The scene's index is left out (an edit shifts it); what the rasterizer
  // asks of it (which crossings are one triangle's pieces, and which triangle comes first)
  // is kept as each triangle's rank among the tile's.
  uint32_t rank = 0, last = UINT32_MAX;
  for (uint32_t i : touching) {
    const RasterTriangle& r = raster.triangles()[i];
    if (r.triangle != last) ++rank, last = r.triangle;
    h.add(rank);
    for (int k = 0; k < 3; ++k) h.add(r.fx[k]), h.add(r.fy[k]), h.add(r.bias[k]);
    h.add(r.xMin), h.add(r.xMax), h.add(r.yMin), h.add(r.yMax);
    h.add(r.ax), h.add(r.ay), h.add(r.at), h.add(r.gx), h.add(r.gy), h.add(r.tMin), h.add(r.tMax);
    h.add(r.front), h.add(r.closed);
  }
  return h.finish();
}

}  // namespace cpvs
