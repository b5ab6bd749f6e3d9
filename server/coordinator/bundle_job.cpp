#include "coordinator/bundle_job.h"

#include <algorithm>

#include "cpvs/bake/bake_lights.h"
#include "cpvs/base/error.h"
#include "cpvs/dag/packed_dag.h"
#include "cpvs/net/convert.h"
#include "coordinator/stored_spec.h"

namespace cpvs::server {

JobGrid jobGridOf(const BundleGrid& g, double closest) { return {gridSpecOf(g.grid, g.tanCone), g.light, closest}; }

OrthoGrid sunGridOf(const JobRecord& j) {
  if (j.isBundle() || j.grids.size() != 1) throw FormatError("job " + j.id + " is not a sun bake of one grid");
  try {
    return orthoGridOf(j.grids[0].grid, "job " + j.id + "'s grid");
  } catch (const InputError& e) {
    throw FormatError(e.what());
  }
}

GridTiles tilesOf(const JobRecord& j) {
  std::vector<int> resolutions;
  for (const JobGrid& g : j.grids) resolutions.push_back(g.grid.log2Resolution);
  return GridTiles(resolutions, j.options.log2TileSize);
}

uint64_t resolutionOf(const JobRecord& j) {
  int finest = 0;
  for (const JobGrid& g : j.grids) finest = std::max(finest, g.grid.log2Resolution);
  return uint64_t(1) << finest;
}

LightBundle bundleOf(const JobRecord& j, std::vector<Dag>&& dags, int pointerGridLevels) {
  LightBundle b;
  b.options = j.options;
  b.sceneHash = parseHashHex(j.geometryHash, "the job's geometry hash");
  b.receiverHash = j.receiverHash;
  const v1::LightList lights = lightListOf(j);
  for (int i = 0; i < lights.lights_size(); ++i) b.lights.push_back({net::fromProto(lights.lights(i)), 0, 0});
  std::vector<double> closest;
  for (size_t k = 0; k < j.grids.size(); ++k) {
    const JobGrid& g = j.grids[k];
    if (g.light >= b.lights.size()) throw FormatError("job " + j.id + ": grid " + std::to_string(k) + " has no light");
    BundleLight& l = b.lights[g.light];
    if (l.gridCount == 0) l.firstGrid = uint32_t(k);
    ++l.gridCount;
    b.grids.push_back({perspectiveGridOf(g.grid, "job " + j.id + ": grid " + std::to_string(k)), g.grid.tanCone, g.light, 0});
    closest.push_back(g.closest);
  }
  finishLightBundle(b, std::move(dags), closest);
  return pointerGridLevels == kMaxGridLevels ? b : withPointerGrids(b, pointerGridLevels);
}

}  // namespace cpvs::server
