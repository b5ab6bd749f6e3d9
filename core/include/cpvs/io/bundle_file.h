// The light bundle (.cpvs format version 4): many local lights of one scene, their grids,
// and one node pool that every grid's DAG shares by content (seed 000 §6.1).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/base/file.h"
#include "cpvs/base/hash.h"
#include "cpvs/dag/packed_dag.h"
#include "cpvs/light/light.h"
#include "cpvs/light/perspective_grid.h"

namespace cpvs {

/// The longest light name a bundle stores, in bytes of UTF-8.
constexpr size_t kMaxLightNameBytes = 256;
/// The most slice boundaries (R + 1 per grid) a bundle's grids hold together: each grid
/// keeps its table in memory (8 bytes a boundary, 1 GiB in all).
constexpr uint64_t kMaxBundleSlices = uint64_t(1) << 27;

/// One grid of a bundle: a spot light's, or one face of a point light's cube.
struct BundleGrid {
  PerspectiveGrid grid;
  double tanCone = 0;   // the cone its texels are cut off by
  uint32_t light = 0;   // the light it belongs to
  uint64_t bytes = 0;   // node bytes of its DAG alone (reachableBytes)
};

/// A light and the range of its grids (contiguous, in light order).
struct BundleLight {
  Light light;  // as given (near and resolution 0 where they were planned)
  uint32_t firstGrid = 0, gridCount = 0;
};

/// Many local lights baked for one scene: what `cpvs bake --spot/--point/--lights` writes.
struct LightBundle {
  BakeOptions options;  // receivers and receiverPcf: what every grid was baked for
  Hash128 sceneHash;
  Hash128 receiverHash;  // receiverHash of the declaration (zero: receivers everywhere)
  std::string plan;  // JSON: what the planner chose per grid
  std::vector<BundleLight> lights;
  std::vector<BundleGrid> grids;
  /// The packed pool (packPool): grid k's header at word 48 k, every node stored once.
  std::shared_ptr<const std::vector<uint32_t>> pool;

  /// Grid k's DAG for lookups, sharing the pool.
  PackedDag dag(size_t grid) const { return PackedDag(pool, grid, grids.at(grid).bytes); }
  /// Node bytes of the pool (NodePool::bytes): what the bundle stores.
  uint64_t poolBytes = 0;
  /// Node bytes of light i's grids, each counted alone: what separate DAGs would store.
  uint64_t lightBytes(size_t light) const;
};

/// The same bundle with every grid's pointer grid (seed 000 §6.3) `levels` deep, or as
/// deep as its resolution allows (packedGridLevels) when that is less; 0: none, every
/// walk starts at the root. The same nodes and answers in another layout: bundles are
/// baked with the deepest. InputError for levels outside [0, kMaxGridLevels].
LightBundle withPointerGrids(const LightBundle& bundle, int levels);

/// Serializes a bundle. Layout (little-endian, in the .cpvs container: magic "CPVS",
/// version 4, flags): the options and scene hash as in version 3, the receiver
/// declaration and the plan; the light count and grid count; per light its kind (and 7
/// zero bytes), position, direction, cone, range, colour, intensity, near, resolution,
/// first grid, grid count and name (a 16-bit byte count and UTF-8); per grid its frame
/// (dir, u, v), tan of its half-angle, tan of its cone, near, far, resolution, light
/// index and bytes; the pool's word count and its words, optionally
/// zstd-compressed; an XXH3-64 checksum of everything before it.
std::vector<uint8_t> encodeBundle(const LightBundle& bundle, bool zstd);

/// Parses and validates a bundle: every count, light and grid (as the bake would accept
/// it), the pool (parsePackedPool: every header, code, offset and grid entry) and every
/// grid's bytes, before anything is trusted. FormatError naming `source` and what is
/// wrong otherwise, and for a single-light artifact (versions 1 to 3).
LightBundle decodeBundle(const uint8_t* data, size_t size, const std::string& source);

inline void writeBundle(const std::string& path, const LightBundle& b, bool zstd) {
  writeFileAtomic(path, encodeBundle(b, zstd));
}
inline LightBundle readBundle(const std::string& path) {
  auto bytes = readFile(path);
  return decodeBundle(bytes.data(), bytes.size(), path);
}

}  // namespace cpvs
