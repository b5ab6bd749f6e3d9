// The .dmh artifact: a DAG-MH (seed 001), the sun's shadows as a compressed shadow map,
// with the header fields of a .cpvs (grid, options, scene hash, receivers).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/base/file.h"
#include "cpvs/base/hash.h"
#include "cpvs/dagmh/dag_mh.h"
#include "cpvs/light/ortho_grid.h"

namespace cpvs {

constexpr uint32_t kDmhFormatVersion = 1;

/// A baked DAG-MH: what was baked and the structure. options.receivers and receiverHash
/// say which points its depths serve, as a .cpvs's do (bake_dag_mh.h).
struct DmhArtifact {
  OrthoGrid grid;  // cubic: depths are in its slices
  BakeOptions options;
  Hash128 sceneHash;
  Hash128 receiverHash;  // of the declaration baked for (receivers.h receiverHash); zero for everywhere
  DagMh dag;
};

/// Serializes an artifact. Layout (little-endian): magic "DGMH", version, flags (bit 0:
/// sections zstd-compressed); the grid, the options and scene hash, the receiver
/// declaration as a .cpvs stores them; the root type, the skip level, the treelet levels
/// (4) and the values per chunk (32), the value count; then sections: the inner nodes'
/// words, the treelets' words, the chunks (5 words each), the factor stream's bytes, the
/// skip list (3 words an entry); an XXH3-64 checksum of everything before it.
std::vector<uint8_t> encodeDmh(const DmhArtifact& artifact, bool zstd);

/// Parses an artifact and validates everything a lookup trusts (validateDagMh) before
/// returning it. FormatError naming `source` and what is wrong otherwise; no allocation
/// beyond what the stored bytes justify.
DmhArtifact decodeDmh(const uint8_t* data, size_t size, const std::string& source);

inline void writeDmh(const std::string& path, const DmhArtifact& a, bool zstd) { writeFileAtomic(path, encodeDmh(a, zstd)); }
inline DmhArtifact readDmh(const std::string& path) {
  auto bytes = readFile(path);
  return decodeDmh(bytes.data(), bytes.size(), path);
}

/// Whether bytes start as a .dmh file does (its magic), to tell artifact kinds apart.
bool isDmh(const uint8_t* data, size_t size);

}  // namespace cpvs
