// What `cpvs-server --check` and `cpvs-worker --check` look at, for probes and people: a
// list of findings printed one a line (ok, warning, FAIL) and an exit status that fails
// on any FAIL. The checks of the local machine every farm process shares live here: the
// folder it writes, its free space, its certificates.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cpvs::metrics {

class Checks {
 public:
  /// Records a finding: passed, or failed (`warnOnly`: a warning that does not fail).
  void check(bool passed, const std::string& what, bool warnOnly = false);
  /// The folder takes a file (created, synced and removed): not full, not read-only.
  void folderWritable(const std::string& dir);
  /// At least `minBytes` free for this process' user in the folder's file system.
  void freeSpace(const std::string& dir, uint64_t minBytes);
  /// A PEM certificate (the first of a chain) that parses and is valid now; a warning
  /// within `warnDays` of its end.
  void certificate(const std::string& pemPath, const char* role, int warnDays = 14);
  /// Prints the findings; 0 when none failed, 1 otherwise.
  int finish() const;
  bool failed() const { return failed_; }

 private:
  std::vector<std::string> lines_;
  bool failed_ = false;
};

/// The first DNS name (or IP address) a PEM certificate holds; empty when it holds none.
std::string certificateName(const std::string& pemPath);

}  // namespace cpvs::metrics
