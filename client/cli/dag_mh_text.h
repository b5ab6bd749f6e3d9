// How `bake` and `inspect` show a DAG-MH: its composition as seed 001's Tables 3 and 4
// (structure and values), for people and as JSON.
#pragma once

#include <string>

#include "cpvs/io/dmh_file.h"

namespace cpvs::cli {

/// The structure (inner nodes, treelets, their bytes), the values (count, chunk map,
/// factor bytes, the share of factors and their mean width, raw ones), the skip list, the
/// total against a 32-bit float map of the same texels.
std::string dagMhTable(const DagMh& dag);
/// The same as JSON fields (no enclosing braces).
std::string dagMhJsonFields(const DmhArtifact& artifact);

}  // namespace cpvs::cli
