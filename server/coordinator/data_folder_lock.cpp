#include "coordinator/data_folder_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "cpvs/base/error.h"
#include "cpvs/base/file.h"

namespace cpvs::server {

DataFolderLock::DataFolderLock(const std::string& dataDir) {
  createFolderDurably(dataDir);  // durable: the store and every result go in it
  const std::string path = (std::filesystem::path(dataDir) / "lock").string();
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) throw InputError("cannot open " + path + ": " + std::strerror(errno));
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int e = errno;
    ::close(fd_);
    fd_ = -1;
    if (e == EWOULDBLOCK)
      throw InputError("the data folder " + dataDir + " is in use by another cpvs-server; give each one its own --data");
    throw InputError("cannot lock " + path + ": " + std::strerror(e));
  }
}

DataFolderLock::~DataFolderLock() {
  if (fd_ >= 0) ::close(fd_);
}

}  // namespace cpvs::server
