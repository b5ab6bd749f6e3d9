// A DAG-MH job as the farm bakes it (NOTES §2.5): what a sun spec must be to make one, the
// parts a worker sends for a tile (checked, or made here for tiles nothing casts on or no
// receiver reads), and the .dmh their builder makes.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cpvs/dagmh/dag_mh.h"
#include "cpvs/v1/farm.pb.h"
#include "store/farm_store.h"

namespace cpvs::server {

/// Whether the job makes a DAG-MH (its spec's format).
bool isDagMhJob(const JobRecord& j);

/// InputError unless a sun spec of these options and resolution can make a DAG-MH (the
/// sun, a cubic grid up to 64K, the raster renderer, no media, tiles of at least 16
/// texels), naming the field.
void checkDagMhSpec(const v1::BakeSpec& spec, const BakeOptions& options, int log2Resolution);

/// The builder of a job's DAG-MH, its tiles the parts of the farm's.
std::unique_ptr<DagMhBuilder> dagMhBuilderOf(const JobRecord& j);

/// The parts of job tile `tile`: its result's bytes decoded and checked (validateDagMhTile,
/// checkDagMhFarmTile), or, for a tile the plan found untouched or unread (bytes empty),
/// all lit. InputError naming `source`.
std::vector<DagMhTile> dagMhPartsOf(const JobRecord& j, uint64_t tile, const std::vector<uint8_t>& bytes,
                                    const std::string& source);

/// The job's .dmh file (zstd sections) of its built DAG-MH.
std::vector<uint8_t> dmhFileOf(const JobRecord& j, DagMh&& dag);

}  // namespace cpvs::server
