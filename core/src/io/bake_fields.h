// The fields every artifact of a bake records besides its lights: the options, the scene
// hash, the receiver declaration and the plan, written and validated once for the
// single-light file and the light bundle. Private to io.
#pragma once

#include <string>

#include "cpvs/bake/options.h"
#include "cpvs/base/hash.h"
#include "cpvs/io/cpvs_file.h"
#include "io/byte_io.h"
#include "io/container.h"

namespace cpvs {

/// The .cpvs container of every version: single-light artifacts up to kCpvsFormatVersion,
/// light bundles at kBundleFormatVersion. Each reader refuses the other's versions by name.
constexpr ContainerKind kCpvsKind{{'C', 'P', 'V', 'S'}, kBundleFormatVersion, kCpvsOldestFormatVersion, ".cpvs file"};

/// The options and the scene hash (every version).
void putOptions(ByteWriter& w, const BakeOptions& options, const Hash128& sceneHash);
void getOptions(ByteReader& h, BakeOptions& options, Hash128& sceneHash);
/// The receiver declaration and the plan (version 3 on).
void putReceiversAndPlan(ByteWriter& w, const BakeOptions& options, const Hash128& receiverHash, const std::string& plan);
void getReceiversAndPlan(ByteReader& h, BakeOptions& options, Hash128& receiverHash, std::string& plan);

}  // namespace cpvs
