// The fields every artifact of a bake records besides its lights: the options, the scene
// hash, the receiver declaration and the plan, written and validated once for the
// single-light file and the light bundle. Private to io.
#pragma once

#include <string>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/base/hash.h"
#include "cpvs/io/cpvs_file.h"
#include "io/byte_io.h"
#include "io/container.h"

namespace cpvs {

/// The .cpvs container of every version: single-light artifacts up to kCpvsFormatVersion,
/// light bundles at kBundleFormatVersion. Each reader refuses the other's versions by name.
constexpr ContainerKind kCpvsKind{{'C', 'P', 'V', 'S'}, kBundleFormatVersion, kCpvsOldestFormatVersion, ".cpvs file"};

/// The sun's grid (every version of .cpvs, and .dmh): FormatError for a grid that is not one.
void putOrthoGrid(ByteWriter& w, const OrthoGrid& grid);
OrthoGrid getOrthoGrid(ByteReader& h);
/// The options and the scene hash (every version).
void putOptions(ByteWriter& w, const BakeOptions& options, const Hash128& sceneHash);
void getOptions(ByteReader& h, BakeOptions& options, Hash128& sceneHash);
/// The receiver declaration and the plan (version 3 on).
void putReceiversAndPlan(ByteWriter& w, const BakeOptions& options, const Hash128& receiverHash, const std::string& plan);
void getReceiversAndPlan(ByteReader& h, BakeOptions& options, Hash128& receiverHash, std::string& plan);

/// A packed word array (packed_layout.h) as the last section: its word count, then its
/// words, zstd-compressed when asked.
void putWordSection(ByteWriter& w, const std::vector<uint32_t>& words, bool zstd);
/// Reads one: "<what> word count N is invalid" unless minWords <= N <= maxWords and
/// N < 2^32 (checked before anything is decompressed); the section must hold exactly
/// those words.
std::vector<uint32_t> getWordSection(ByteReader& h, bool zstd, uint64_t minWords, const char* what,
                                     uint64_t maxWords = UINT32_MAX);

}  // namespace cpvs
