// What every DAG the core builds must satisfy, checked in one place: after compression
// and after a merge (CPVS_DCHECK, debug builds), and by the tests.
#pragma once

#include <string>

#include "cpvs/dag/dag.h"

namespace cpvs {

/// "" when the DAG is well formed, else what is wrong: child ranges that match their
/// codes, every code valid, every reference inside the level below (and every root's
/// inside the top level), hashes (when held) one per node; and when `canonical`, every
/// level in strictly increasing (hash, content) order, so free of duplicates.
std::string dagInvariantViolation(const Dag& dag, bool canonical);

/// The same as a test: true when dagInvariantViolation is "".
inline bool dagInvariantsHold(const Dag& dag, bool canonical) { return dagInvariantViolation(dag, canonical).empty(); }

}  // namespace cpvs
