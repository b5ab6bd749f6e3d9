#include "coordinator/dag_mh_job.h"

#include <algorithm>

#include "coordinator/bundle_job.h"
#include "coordinator/stored_spec.h"
#include "cpvs/bake/bake_dag_mh.h"
#include "cpvs/base/error.h"
#include "cpvs/io/dmh_file.h"
#include "cpvs/io/dmh_tile_file.h"

namespace cpvs::server {

bool isDagMhJob(const JobRecord& j) { return !j.isBundle() && bakeSpecOf(j).format() == v1::ARTIFACT_FORMAT_DAG_MH; }

void checkDagMhSpec(const v1::BakeSpec& spec, const BakeOptions& options, int log2Resolution) {
  if (log2Resolution > kMaxLog2DagMhResolution)
    throw InputError("resolution " + spec.resolution() + ": a DAG-MH is baked up to " +
                     std::to_string(1u << kMaxLog2DagMhResolution) + " texels a side");
  if (spec.options().depth_slices() != 0) throw InputError("options.depth_slices: a DAG-MH's grid is cubic");
  if (spec.media_size() > 0) throw InputError("media are read through a CPVS's voxels, not a DAG-MH");
  if (options.renderer != Renderer::Raster) throw InputError("options.renderer: a DAG-MH is baked by the raster renderer");
  if (log2Resolution > options.log2TileSize && options.log2TileSize < 4)
    throw InputError("options.tile_size: a DAG-MH's tiles are at least 16 texels a side");
}

std::unique_ptr<DagMhBuilder> dagMhBuilderOf(const JobRecord& j) {
  const int log2R = sunGridOf(j).log2Resolution;
  return std::make_unique<DagMhBuilder>(log2R, dagMhPartLog2(log2R, j.options.log2TileSize));
}

std::vector<DagMhTile> dagMhPartsOf(const JobRecord& j, uint64_t tile, const std::vector<uint8_t>& bytes,
                                    const std::string& source) {
  const int log2R = sunGridOf(j).log2Resolution;
  const TileCoord at = tilesOf(j).at(tile).tile;
  if (bytes.empty()) return litDagMhFarmTile(log2R, j.options.log2TileSize, at.x, at.y);
  // The parts this job's tiles have, known before a byte of them is decompressed.
  const DagMhTileShape shape = dagMhFarmTileShape(log2R, j.options.log2TileSize);
  std::vector<DagMhTile> parts = decodeDagMhTiles(bytes.data(), bytes.size(), source, &shape);
  checkDagMhFarmTile(parts, log2R, j.options.log2TileSize, at.x, at.y, source);
  return parts;
}

std::vector<uint8_t> dmhFileOf(const JobRecord& j, DagMh&& dag) {
  DmhArtifact art;
  art.grid = sunGridOf(j);
  art.options = j.options;
  art.sceneHash = parseHashHex(j.geometryHash, "the job's geometry hash");
  art.receiverHash = j.receiverHash;
  art.dag = std::move(dag);
  return encodeDmh(art, true);
}

}  // namespace cpvs::server
