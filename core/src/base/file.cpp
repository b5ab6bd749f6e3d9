#include "cpvs/base/file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "cpvs/base/error.h"

namespace cpvs {

namespace {

[[noreturn]] void fail(const std::string& what, const std::string& path, int error) {
  throw InputError("cannot " + what + " " + path + ": " + std::strerror(error));
}

// A name unique to this write: process, then a counter shared by the process's threads.
std::string temporaryName(const std::string& path) {
  static std::atomic<uint64_t> counter{0};
  return path + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter.fetch_add(1));
}

// Writes all of data to fd at its current offset; the errno of the failure, 0 on success.
int writeAll(int fd, const void* data, size_t size) {
  const char* p = static_cast<const char*>(data);
  for (size_t done = 0; done < size;) {
    const ssize_t n = ::write(fd, p + done, size - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    done += size_t(n);
  }
  return 0;
}

}  // namespace

void checkOutputFolder(const std::string& path, const std::string& flag) {
  namespace fs = std::filesystem;
  const fs::path folder = fs::path(path).parent_path().empty() ? fs::path(".") : fs::path(path).parent_path();
  std::error_code ec;
  if (fs::is_directory(fs::status(path, ec))) throw InputError(flag + " " + path + ": is a folder; name a file in it");
  const fs::file_status st = fs::status(folder, ec);
  if (!fs::exists(st))
    throw InputError(flag + " " + path + ": the folder " + folder.string() + " does not exist");
  if (!fs::is_directory(st)) throw InputError(flag + " " + path + ": " + folder.string() + " is not a folder");
  if (::access(folder.c_str(), W_OK | X_OK) != 0)
    throw InputError(flag + " " + path + ": the folder " + folder.string() + " is not writable (" + std::strerror(errno) + ")");
}

void syncParentFolder(const std::string& path) {
  std::string folder = std::filesystem::path(path).parent_path().string();
  if (folder.empty()) folder = ".";
  int fd = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd < 0) fail("open folder", folder, errno);
  if (::fsync(fd) != 0) {
    int e = errno;
    ::close(fd);
    fail("sync folder", folder, e);
  }
  ::close(fd);
}

void createFolderDurably(const std::string& path) {
  namespace fs = std::filesystem;
  std::vector<fs::path> missing;
  std::error_code ec;
  for (fs::path p = fs::path(path).lexically_normal(); !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
    missing.push_back(p);
    if (p == p.parent_path()) break;
  }
  for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
    if (!fs::create_directory(*it, ec) && ec) fail("create folder", it->string(), ec.value());
    syncParentFolder(it->string());
  }
}

void writeFileAtomic(const std::string& path, const std::vector<uint8_t>& bytes) {
  const std::string tmp = temporaryName(path);
  int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd < 0) fail("write", path, errno);
  if (const int e = writeAll(fd, bytes.data(), bytes.size()); e != 0) {
    ::close(fd);
    ::unlink(tmp.c_str());
    fail("write", path, e);
  }
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    int e = errno;
    ::unlink(tmp.c_str());
    fail("write", path, e);
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    int e = errno;
    ::unlink(tmp.c_str());
    fail("write", path, e);
  }
  syncParentFolder(path);
}

std::vector<uint8_t> readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("open", path, errno);
  in.seekg(0, std::ios::end);
  std::streamoff n = in.tellg();
  if (n < 0) throw InputError("cannot read " + path);
  in.seekg(0);
  std::vector<uint8_t> bytes(static_cast<size_t>(n));
  if (n > 0 && !in.read(reinterpret_cast<char*>(bytes.data()), n)) throw InputError("cannot read " + path);
  return bytes;
}

AppendFile::AppendFile(const std::string& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd_ < 0) fail();
}

AppendFile::~AppendFile() {
  if (fd_ >= 0) ::close(fd_);
}

void AppendFile::write(const void* data, size_t size) {
  if (const int e = writeAll(fd_, data, size); e != 0) {
    errno = e;
    fail();
  }
}

void AppendFile::syncAndClose() {
  const int fd = fd_;
  fd_ = -1;
  if (::fsync(fd) != 0) {
    const int e = errno;
    ::close(fd);
    errno = e;
    fail();
  }
  if (::close(fd) != 0) fail();
}

void replaceTail(const std::string& path, uint64_t keep, const void* data, size_t size) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) fail("write", path, errno);
  int e = 0;
  if (::ftruncate(fd, off_t(keep)) != 0 || ::lseek(fd, off_t(keep), SEEK_SET) < 0) e = errno;
  if (e == 0) e = writeAll(fd, data, size);
  if (e == 0 && ::fdatasync(fd) != 0) e = errno;
  ::close(fd);
  if (e != 0) fail("write", path, e);
  if (keep == 0) syncParentFolder(path);  // the file may be new
}

void AppendFile::fail() const { throw InputError("cannot write " + path_ + ": " + std::strerror(errno)); }

}  // namespace cpvs
