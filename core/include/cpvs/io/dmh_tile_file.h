// Tiles' parts of a DAG-MH as bytes (DagMhTile): what a farm worker sends for a DAG-MH
// job's tile and the coordinator keeps on disk until the job's artifact is written.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cpvs/dagmh/dag_mh.h"

namespace cpvs {

/// Serializes parts (one farm tile holds several of the bake's tiles). Layout: magic
/// "DGMT", version, flags (zstd), the part count, then per part its map and tile sides and
/// place, root, values below, interval and flag, and its sections (each inner level, the
/// treelets, the value intervals), an XXH3-64 checksum.
std::vector<uint8_t> encodeDagMhTiles(const std::vector<DagMhTile>& tiles, bool zstd = true);

/// What a reader that knows expects of the parts (a coordinator: its job's grid and tiles).
struct DagMhTileShape {
  int log2Side = 0, log2TileSide = 0;
  uint32_t parts = 0;
};

/// Parses parts and checks each one (validateDagMhTile), and with `expected` their sides
/// and count, before any section is read. No section is decompressed beyond what its
/// part's geometry can hold. FormatError naming `source` otherwise.
std::vector<DagMhTile> decodeDagMhTiles(const uint8_t* data, size_t size, const std::string& source,
                                        const DagMhTileShape* expected = nullptr);

}  // namespace cpvs
