// Whole-file reads and atomic, durable writes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace cpvs {

/// Writes `bytes` to `path` atomically and durably: a temporary file in the same folder
/// (named by process and thread, so concurrent writers of one path never share it),
/// fsync, rename over `path`, fsync of the folder so the rename survives a power cut.
/// InputError naming the path on any failure; the temporary is removed.
void writeFileAtomic(const std::string& path, const std::vector<uint8_t>& bytes);

/// InputError, starting with `flag` and naming `path`, unless the folder that would hold
/// the file at `path` exists and this process may create files in it and `path` is not a
/// folder itself: checked before
/// long work, so that a typo in an output path costs nothing.
void checkOutputFolder(const std::string& path, const std::string& flag);

/// The whole file; InputError naming the path when it can't be opened or read.
std::vector<uint8_t> readFile(const std::string& path);

/// fsyncs the folder holding `path`, so that a rename or creation in it is durable.
/// InputError naming the folder on failure.
void syncParentFolder(const std::string& path);

/// Creates the folder at `path` and any missing folder above it, syncing the folder that
/// holds each one it creates, so that the new folders survive a power cut. InputError.
void createFolderDurably(const std::string& path);

/// Keeps the first `keep` bytes of the file at `path` (created when absent), writes
/// `data` after them, and syncs it: a resumable transfer that continues exactly at the
/// bytes it acknowledged, whatever a crash left after them. InputError naming the path.
void replaceTail(const std::string& path, uint64_t keep, const void* data, size_t size);

/// A file opened for appending (created when absent), for transfers that resume: data
/// goes in with write(2) and is fsync'ed before the file is renamed into place. Errors are
/// InputError naming the file.
class AppendFile {
 public:
  explicit AppendFile(const std::string& path);
  ~AppendFile();
  AppendFile(const AppendFile&) = delete;
  AppendFile& operator=(const AppendFile&) = delete;

  void write(const void* data, size_t size);
  /// Flushes the data to disk and closes the file.
  void syncAndClose();

 private:
  [[noreturn]] void fail() const;
  std::string path_;
  int fd_ = -1;
};

}  // namespace cpvs
