// What a power cut leaves of a folder, from the journal tests/support/powercut_shim.c kept
// of a process killed at some moment: a file keeps the bytes it had at its last sync (none
// if it was never synced since it was created or truncated), and a name created, made
// or renamed into a folder stays only when that folder was synced after it. The files
// named by `trusted` prefixes keep everything: SQLite syncs its own (synchronous=FULL).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace cpvs::testing {

struct PowerCut {
  std::vector<std::string> removed;    // names that were not durable, gone (folders with what they held)
  std::vector<std::string> truncated;  // files cut back to their last synced size
};

/// Applies the power cut to `folder` (the shim's CPVS_POWERCUT_DIR) from `journal`.
PowerCut dropUnsyncedWrites(const std::string& journal, const std::string& folder,
                            const std::vector<std::string>& trusted = {"farm.sqlite"});

}  // namespace cpvs::testing
