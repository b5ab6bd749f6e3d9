// A tile's sub-DAG as bytes: what a worker sends the coordinator and the coordinator keeps
// on disk until the job's merge is done.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cpvs/dag/dag.h"
#include "cpvs/dag/compress.h"

namespace cpvs {

/// Serializes a sub-DAG (levels and roots; hashes are left out: the receiver recomputes
/// them from the content). Layout: magic "CPVT", version, flags (zstd), log2 resolution,
/// log2 root size, the roots, the level section of the .cpvs file, an XXH3-64 checksum.
std::vector<uint8_t> encodeSubDag(const Dag& dag, bool zstd = true);

/// Parses a sub-DAG and checks everything a merge relies on: sizes against the data,
/// child codes and indices, roots in increasing key order with valid references, and,
/// when `canonical`, that every level is in (hash, content) order without duplicates
/// (hashes recomputed with `hash`). Throws InputError naming `source` otherwise.
Dag decodeSubDag(const uint8_t* data, size_t size, const std::string& source, bool canonical, HashKind hash);

/// Checks that `dag` holds exactly the blocks of tile (tileX, tileY): roots of size
/// 2^log2TileSize at (tileX, tileY, z) for every z. InputError naming `source` otherwise.
void checkTileRoots(const Dag& dag, uint64_t tileX, uint64_t tileY, int log2TileSize, const std::string& source);

}  // namespace cpvs
