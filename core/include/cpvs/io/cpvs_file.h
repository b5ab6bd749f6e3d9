// The .cpvs artifact: header (light frame, grid, options), the DAG levels, a checksum.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/base/file.h"
#include "cpvs/dag/dag.h"
#include "cpvs/dag/packed_dag.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/psv/top_tree.h"

namespace cpvs {

/// Version 3 adds the receiver declaration to the header; version 2 stores the DAG as its
/// packed array (packed_layout.h); version 1 stored its levels. Versions 1 and 2 are still
/// read (as baked for receivers everywhere).
constexpr uint32_t kCpvsFormatVersion = 3;
constexpr uint32_t kCpvsOldestFormatVersion = 1;
/// Version 4 is a light bundle (bundle_file.h): many local lights, one node pool.
constexpr uint32_t kBundleFormatVersion = 4;
/// The largest plan a file may record.
constexpr uint32_t kMaxPlanBytes = 1u << 20;

/// A baked artifact: what was baked (grid, options, scene hash) and the complete DAG.
struct CpvsArtifact {
  OrthoGrid grid;
  BakeOptions options;
  Hash128 sceneHash;
  /// receiverHash of the declaration baked for (zero for receivers everywhere): with
  /// options.receivers and options.receiverPcf, what `verify` samples and lookups may trust.
  Hash128 receiverHash;
  /// The bake's plan (planJson: what it computed and why), as recorded; "" when none
  /// (files before version 3).
  std::string plan;
  Dag dag;  // complete: one root, log2RootSize == log2Resolution; hashes not stored
  /// The same DAG packed for lookups: decodeCpvs fills it with the file's words as they
  /// are (packing a version 1 file's levels); encodeCpvs ignores it and packs `dag`.
  PackedDag packed;
  /// The format version the file was written in (decodeCpvs); encodeCpvs writes the current.
  uint32_t formatVersion = kCpvsFormatVersion;
  /// The TOP tree of the scene's translucent casters for the sun (translucentTree), whose
  /// transmittance multiplies the CPVS's answer; null when the scene has none (nor does
  /// the file: opaque scenes keep their bytes).
  std::shared_ptr<const TopTree> translucent;
};

/// Serializes an artifact. Layout (little-endian): a fixed header with magic "CPVS",
/// version, flags, the grid and options, the scene hash, the receiver declaration (kind,
/// PCF width, 6 reserved zero bytes, its hash), the plan (a byte count and UTF-8 JSON,
/// at most kMaxPlanBytes); the word count of the packed DAG and its words
/// (packed_layout.h: a header, the pointer grid, the nodes, the leaves), optionally
/// zstd-compressed; with flag 2, the translucent casters' TOP tree (io/top_section.h); an
/// XXH3-64 checksum of everything before it. (Version 1 held the
/// root, the level sizes and per level the 16-bit codes and 32-bit child indices.)
std::vector<uint8_t> encodeCpvs(const CpvsArtifact& artifact, bool zstd);

/// Parses and validates an artifact: every size against the data present, the checksum,
/// every child code and index, the translucent casters' tree (TopTree::fromNodes), before
/// anything is trusted. Throws InputError naming
/// `source` and what is wrong for a truncated, corrupted or foreign file.
CpvsArtifact decodeCpvs(const uint8_t* data, size_t size, const std::string& source);

inline void writeCpvs(const std::string& path, const CpvsArtifact& a, bool zstd) {
  writeFileAtomic(path, encodeCpvs(a, zstd));
}
inline CpvsArtifact readCpvs(const std::string& path) {
  auto bytes = readFile(path);
  return decodeCpvs(bytes.data(), bytes.size(), path);
}

/// The format version of a .cpvs file's bytes (which reader takes it), after its magic;
/// FormatError naming `source` for bytes that are not a .cpvs file.
uint32_t cpvsFormatVersion(const uint8_t* data, size_t size, const std::string& source);

}  // namespace cpvs
