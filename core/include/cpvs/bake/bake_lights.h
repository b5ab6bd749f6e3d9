// A bake of many local lights in one process: every light checked and planned, every
// grid baked, their DAGs shared in one node pool (the light bundle, bundle_file.h).
#pragma once

#include <string>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/bake/receivers.h"
#include "cpvs/bake/stage_times.h"
#include "cpvs/base/progress.h"
#include "cpvs/dag/dag.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/light/light.h"

namespace cpvs {

struct Scene;

/// What bakeLights bakes, without baking: the same checks (receivers, the lights, the
/// slice budget), each light's grids planned, every grid's bytes 0 and no pool.
/// `closest` receives each grid's closest geometry (LightGridPlan::closest). What
/// `cpvs plan` prints for local lights. `receivers` is the declaration options.receivers
/// and options.receiverPcf name (InputError when they differ, or it is not valid).
LightBundle planLights(const Scene& scene, const std::vector<Light>& lights, double footprint, const BakeOptions& options,
                       std::vector<double>& closest, const ReceiverDeclaration& receivers = {});

/// Checks every light against the scene (checkLightCount, checkLight) and plans its grids
/// (planLightGrids with `footprint`) before any bake starts, then bakes each grid as
/// bakeGrid does (options.renderer, tiles of options.log2TileSize) and shares their
/// nodes (shareNodes). The bytes depend only on the scene, the lights in their order,
/// the footprint, the options and the receivers. `sceneHash` is recorded. Every grid
/// keeps what the declared `receivers` read (ReceiverSet on its spot grid; the whole
/// scene's surfaces receive, a light's fixture included); its hash is recorded.
/// InputError for bad lights and receivers; Cancelled when `progress` returns false
/// (stage "lights": grids done of all; called from one thread at a time, not always the
/// caller's). Grids bake side by side; `times` sums their stages, `gridSeconds` receives
/// each grid's wall seconds.
LightBundle bakeLights(const Scene& scene, const std::vector<Light>& lights, double footprint,
                       const BakeOptions& options, const Hash128& sceneHash, StageTimes* times = nullptr,
                       const ProgressFn& progress = nullptr, std::vector<double>* gridSeconds = nullptr,
                       const ReceiverDeclaration& receivers = {});

/// Ends a bake of `bundle`'s planned grids (planLights) from their DAGs, dags[k] grid k's
/// as bakeGrid bakes it: the nodes shared in grid order (shareNodes), each grid's bytes,
/// the pool packed with the deepest pointer grids, and the plan with each grid's
/// `closest`. What bakeLights and the farm's coordinator both end with: the bytes depend
/// on the plan and the DAGs alone, not on where or in what order the grids were baked.
void finishLightBundle(LightBundle& bundle, std::vector<Dag>&& dags, const std::vector<double>& closest);

/// The scene a light with the fixture `exclude` (Light::exclude) casts shadows with:
/// `scene` itself when there is none, else `storage`, filled with the scene without it
/// (withoutMeshes, errors naming `source`). What its grids are planned and baked with,
/// here and on the farm.
const Scene& castersOf(const Scene& scene, const std::vector<std::string>& exclude, const std::string& source,
                       Scene& storage);

/// The footprint a bake of local lights plans with when none is given: the scene's
/// bounding-box diagonal / 4096.
double defaultFootprint(const Scene& scene);

/// The scene file's point, spot and area lights (a spot light's cone is its outer one; the
/// procedural city's are its street lamps; an area light with a size its kDefaultVpls
/// VPLs, area_light.h, seeded by its number), in the file's order; the others cast no
/// shadow a bundle holds (directional: a sun bake; ambient: none). A spot light
/// whose cone is wider than kMaxConeDeg is baked as a point light (its axis and cone
/// kept for shading). A light whose node also places meshes (glTF's lamp node with its
/// bulb) has them as its fixture: `exclude` holds the node's name, unless a mesh or
/// material of another node has that name too (none then: name it in a lights file).
std::vector<Light> sceneLights(const Scene& scene);
/// Whether a scene file's area light has a rectangle (assimp gives some without a size).
bool sceneAreaLightHasSize(const SceneLight& light);

/// The scene's own lights (sceneLights) first, then `given`, whose area lights are
/// numbered after the scene's: the order a bake, a plan and the farm list them in. A scene with none is an InputError that starts with `what`
/// (the flag or field that asked for them, and the scene).
std::vector<Light> withSceneLights(const Scene& scene, std::vector<Light> given, const std::string& what);

/// What the planner chose, one JSON object per grid, and each fixture left out (the
/// bundle's plan: the light table does not hold them).
std::string lightPlanJson(const LightBundle& bundle, const std::vector<double>& closest);

}  // namespace cpvs
