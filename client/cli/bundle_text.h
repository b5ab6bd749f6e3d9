// How `bake` and `inspect` show a light bundle: a table of its lights for people, JSON
// for scripts.
#pragma once

#include <string>

#include "cpvs/io/bundle_file.h"

namespace cpvs::cli {

/// One line per light (kind, position, grids, resolution, near and far, bytes alone),
/// then the pool against separate DAGs and against 16-bit shadow maps of the same grids.
std::string bundleTable(const LightBundle& bundle);
/// {"lights": [...], "grids": ..., "pool_bytes": ..., "separate_bytes": ...,
/// "shadow_map_bytes": ...}: the same as JSON fields (no enclosing braces).
std::string bundleJsonFields(const LightBundle& bundle);
/// Sum over the bundle's grids of a 16-bit R x R shadow map's bytes.
uint64_t bundleShadowMapBytes(const LightBundle& bundle);

}  // namespace cpvs::cli
