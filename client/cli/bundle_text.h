// How `bake` and `inspect` show a light bundle: a table of its lights for people, JSON
// for scripts.
#pragma once

#include <string>
#include <vector>

#include "cpvs/bake/receivers.h"
#include "cpvs/io/bundle_file.h"

namespace cpvs::cli {

/// One line per light (kind, position, grids, resolution, near and far, bytes alone),
/// then the pool against separate DAGs and against 16-bit shadow maps of the same grids,
/// and the receivers it was baked for.
std::string bundleTable(const LightBundle& bundle);
/// {"lights": [...], "grids": ..., "pool_bytes": ..., "separate_bytes": ...,
/// "shadow_map_bytes": ..., "receivers": ...}: the same as JSON fields (no enclosing braces).
std::string bundleJsonFields(const LightBundle& bundle);
/// What `cpvs plan` prints for local lights (a bundle as planLights plans it, `closest`
/// per grid): one line per light (kind, position, grids, resolution, near and far, the
/// closest geometry its grids see, the widest texel at far), then what 16-bit shadow maps
/// of those grids would hold, and the receivers declared.
std::string lightPlanTable(const LightBundle& planned, const std::vector<double>& closest, double footprint,
                           const ReceiverDeclaration& receivers);
/// Sum over the bundle's grids of a 16-bit R x R shadow map's bytes.
uint64_t bundleShadowMapBytes(const LightBundle& bundle);

}  // namespace cpvs::cli
