// A bake of many local lights in one process: every light checked and planned, every
// grid baked, their DAGs shared in one node pool (the light bundle, bundle_file.h).
#pragma once

#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/bake/stage_times.h"
#include "cpvs/base/progress.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/light/light.h"

namespace cpvs {

struct Scene;

/// Checks every light against the scene (checkLightCount, checkLight) and plans its grids
/// (planLightGrids with `footprint`) before any bake starts, then bakes each grid as
/// bakeGrid does (options.renderer, tiles of options.log2TileSize) and shares their
/// nodes (shareNodes). The bytes depend only on the scene, the lights in their order,
/// the footprint and the options. `sceneHash` is recorded. InputError for bad lights
/// and for receivers other than everywhere (local lights declare none yet); Cancelled
/// when `progress` returns false (stage "lights": grids done of all).
LightBundle bakeLights(const Scene& scene, const std::vector<Light>& lights, double footprint,
                       const BakeOptions& options, const Hash128& sceneHash, StageTimes* times = nullptr,
                       const ProgressFn& progress = nullptr);

/// What the planner chose, one JSON object per grid (the bundle's plan).
std::string lightPlanJson(const LightBundle& bundle, const std::vector<double>& closest);

}  // namespace cpvs
