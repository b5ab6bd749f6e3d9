#include "cpvs/io/sub_dag_file.h"

#include "cpvs/light/frame.h"
#include "cpvs/light/ortho_grid.h"
#include "io/container.h"
#include "io/level_section.h"
#include "cpvs/dag/invariants.h"

namespace cpvs {

namespace {

constexpr ContainerKind kSubDagKind{{'C', 'P', 'V', 'T'}, 1, 1, "sub-DAG"};

}  // namespace

std::vector<uint8_t> encodeSubDag(const Dag& dag, bool zstd) {
  ByteWriter w;
  beginContainer(w, kSubDagKind, zstd ? kContainerZstd : 0);
  w.put<int32_t>(dag.log2Resolution);
  w.put<int32_t>(dag.log2RootSize);
  w.put<uint64_t>(dag.roots.size());
  for (const auto& r : dag.roots) {
    w.put<uint64_t>(r.key);
    w.put<uint32_t>(r.ref.code);
    w.put<uint32_t>(r.ref.index);
  }
  writeDagLevels(dag, zstd, w);
  return sealContainer(std::move(w));
}

Dag decodeSubDag(const uint8_t* data, size_t size, const std::string& source, bool canonical, HashKind hash) {
  uint32_t flags = 0, version = 0;
  ByteReader h = openContainer(data, size, source, kSubDagKind, kContainerZstd, flags, version);
  int log2R = h.get<int32_t>("header"), log2Root = h.get<int32_t>("header");
  if (log2R < kMinLog2Resolution || log2R > kMaxLog2Resolution || log2Root < 3 || log2Root > log2R)
    h.fail("resolution 2^" + std::to_string(log2R) + " with roots of 2^" + std::to_string(log2Root) +
           " is out of range");
  uint64_t rootCount = h.get<uint64_t>("roots");
  if (rootCount > h.remaining() / 16) h.fail("root count " + std::to_string(rootCount) + " exceeds the data");
  Dag dag;
  dag.reset(log2R, log2Root);
  dag.roots.resize(rootCount);
  for (auto& root : dag.roots) {
    root.key = h.get<uint64_t>("roots");
    root.ref.code = h.get<uint32_t>("roots");
    root.ref.index = h.get<uint32_t>("roots");
  }
  const int levels = Dag::internalLevels(log2Root);
  readDagLevels(h, (flags & kContainerZstd) != 0, levels, dag);
  if (h.remaining() != 0) h.fail(std::to_string(h.remaining()) + " unexpected bytes after the payload");

  const uint64_t blocks = uint64_t(1) << (log2R - log2Root);
  const uint64_t top = levels == 0 ? dag.leaves.size() : dag.levels[levels - 1].size();
  for (size_t i = 0; i < dag.roots.size(); ++i) {
    const auto& root = dag.roots[i];
    if (rootKeyX(root.key) >= blocks || rootKeyY(root.key) >= blocks || rootKeyZ(root.key) >= blocks ||
        (i > 0 && dag.roots[i - 1].key >= root.key))
      h.fail("root " + std::to_string(i) + " has an invalid or out-of-order position");
    if (root.ref.code > kRef || (root.ref.code == kRef && root.ref.index >= top))
      h.fail("root " + std::to_string(i) + " has an invalid reference");
  }

  computeHashes(dag, hash);
  if (canonical) {
    // A merge sweeps levels in (hash, content) order: anything else would silently
    // produce duplicates, so it is rejected here.
    const std::string violation = dagInvariantViolation(dag, true);
    if (!violation.empty()) h.fail(violation);
  }
  return dag;
}

void checkTileRoots(const Dag& dag, uint64_t tileX, uint64_t tileY, int log2TileSize, const std::string& source) {
  if (dag.log2RootSize != log2TileSize)
    throw InputError(source + ": roots of size 2^" + std::to_string(dag.log2RootSize) + ", the tile is 2^" +
                     std::to_string(log2TileSize));
  const uint64_t blocks = uint64_t(1) << (dag.log2Resolution - log2TileSize);
  if (dag.roots.size() != blocks)
    throw InputError(source + ": " + std::to_string(dag.roots.size()) + " roots, the tile has " +
                     std::to_string(blocks) + " blocks");
  for (uint64_t z = 0; z < blocks; ++z)
    if (dag.roots[z].key != rootKey(tileX, tileY, z))
      throw InputError(source + ": root " + std::to_string(z) + " is not a block of tile (" + std::to_string(tileX) +
                       ", " + std::to_string(tileY) + ")");
}

}  // namespace cpvs
