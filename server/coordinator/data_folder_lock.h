// One coordinator per data folder: an exclusive lock on a file in it, held for the
// coordinator's life and released by the kernel when the process ends, however it ends.
#pragma once

#include <string>

namespace cpvs::server {

class DataFolderLock {
 public:
  /// Creates the folder when needed and locks it; InputError when another process holds
  /// it (two coordinators would merge, delete and rename under each other).
  explicit DataFolderLock(const std::string& dataDir);
  ~DataFolderLock();
  DataFolderLock(const DataFolderLock&) = delete;
  DataFolderLock& operator=(const DataFolderLock&) = delete;

 private:
  int fd_ = -1;
};

}  // namespace cpvs::server
