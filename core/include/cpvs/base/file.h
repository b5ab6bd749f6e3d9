// Whole-file reads and atomic, durable writes.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cpvs {

/// Writes `bytes` to `path` atomically and durably: a temporary file in the same folder
/// (named by process and thread, so concurrent writers of one path never share it),
/// fsync, rename over `path`, fsync of the folder so the rename survives a power cut.
/// InputError naming the path on any failure; the temporary is removed.
void writeFileAtomic(const std::string& path, const std::vector<uint8_t>& bytes);

/// The whole file; InputError naming the path when it can't be opened or read.
std::vector<uint8_t> readFile(const std::string& path);

/// fsyncs the folder holding `path`, so that a rename or creation in it is durable.
/// InputError naming the folder on failure.
void syncParentFolder(const std::string& path);

}  // namespace cpvs
