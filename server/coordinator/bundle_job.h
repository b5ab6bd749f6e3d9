// A light bundle as the farm bakes it: a job's grids and lights as the store keeps them,
// the tiles they make, and the artifact their DAGs make (the bytes bakeLights writes).
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/bake/tile_plan.h"
#include "cpvs/dag/dag.h"
#include "cpvs/io/bundle_file.h"
#include "store/farm_store.h"

namespace cpvs::server {

/// A planned grid as the store keeps it, with the closest geometry its planner found.
JobGrid jobGridOf(const BundleGrid& g, double closest);

/// A sun job's grid. FormatError for a bundle or a stored grid that is not one.
OrthoGrid sunGridOf(const JobRecord& j);

/// The tiles of a job's grids in lease order (GridTiles: the sun's one grid's TilePlan,
/// or a bundle's grids' one after the other).
GridTiles tilesOf(const JobRecord& j);

/// The finest grid resolution of a job (the sun's grid, or a bundle's finest).
uint64_t resolutionOf(const JobRecord& j);

/// The bundle a job's grids make, dags[k] grid k's (merged from its tiles and assembled
/// as bakeGrid does): its lights, options, scene hash, shared pool, bytes and plan
/// (finishLightBundle), with pointer grids `pointerGridLevels` deep. FormatError for
/// lights the record cannot give back.
LightBundle bundleOf(const JobRecord& j, std::vector<Dag>&& dags, int pointerGridLevels);

}  // namespace cpvs::server
