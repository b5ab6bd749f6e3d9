// The .cpvs artifact: header (light frame, grid, options), the DAG levels, a checksum.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/base/file.h"
#include "cpvs/dag/dag.h"
#include "cpvs/light/ortho_grid.h"

namespace cpvs {

constexpr uint32_t kCpvsFormatVersion = 1;

/// A baked artifact: what was baked (grid, options, scene hash) and the complete DAG.
struct CpvsArtifact {
  OrthoGrid grid;
  BakeOptions options;
  Hash128 sceneHash;
  Dag dag;  // complete: one root, log2RootSize == log2Resolution; hashes not stored
};

/// Serializes an artifact. Layout (little-endian): a fixed header with magic "CPVS",
/// version, flags, the grid and options, the root and the level sizes; the payload
/// (leaves, then per level the 16-bit codes padded to 4 bytes and the 32-bit child
/// indices), optionally zstd-compressed; an XXH3-64 checksum of everything before it.
std::vector<uint8_t> encodeCpvs(const CpvsArtifact& artifact, bool zstd);

/// Parses and validates an artifact: every size against the data present, the checksum,
/// every child code and index, before anything is trusted. Throws InputError naming
/// `source` and what is wrong for a truncated, corrupted or foreign file.
CpvsArtifact decodeCpvs(const uint8_t* data, size_t size, const std::string& source);

inline void writeCpvs(const std::string& path, const CpvsArtifact& a, bool zstd) {
  writeFileAtomic(path, encodeCpvs(a, zstd));
}
inline CpvsArtifact readCpvs(const std::string& path) {
  auto bytes = readFile(path);
  return decodeCpvs(bytes.data(), bytes.size(), path);
}

}  // namespace cpvs
