// The one container of every artifact kind: magic, version and flags first, the body,
// an XXH3-64 checksum of everything before it last; inside the body, sections of bytes,
// stored raw or as one zstd frame. A new artifact kind (a new magic) or a new section
// reuses this, so prologue, checksum and decompression are written and validated once.
// Little-endian, as every supported target is. Private to io.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "io/byte_io.h"

namespace cpvs {

/// What distinguishes one artifact kind from another.
struct ContainerKind {
  char magic[4];
  uint32_t version;     // the version this build writes
  uint32_t minVersion;  // the oldest it still reads (versions in between are read too)
  const char* noun;     // for messages: ".cpvs file", "sub-DAG"
};

/// Flag bit: the body's sections are zstd-compressed.
constexpr uint32_t kContainerZstd = 1;

/// Starts a container: magic, version, flags.
void beginContainer(ByteWriter& w, const ContainerKind& kind, uint32_t flags);
/// Ends it with the checksum of everything written so far; returns the bytes.
std::vector<uint8_t> sealContainer(ByteWriter&& w);

/// Checks magic, version (returned in `version`), then the checksum (before anything else is trusted, so that
/// every later check reports real damage, not a random bit flip), then that `flags`
/// holds no bit outside `knownFlags`. Returns a reader over the body (from the flags on,
/// checksum excluded), positioned after the flags. FormatError naming `source` otherwise.
ByteReader openContainer(const uint8_t* data, size_t size, const std::string& source, const ContainerKind& kind,
                         uint32_t knownFlags, uint32_t& flags, uint32_t& version);

/// Writes a section: its size, the size stored, then its bytes, zstd-compressed when
/// `zstd` (level 9).
void writeSection(ByteWriter& w, const std::vector<uint8_t>& bytes, bool zstd);

/// A compressed section may hold this many bytes whatever its ratio...
constexpr uint64_t kSectionAlwaysAllowedBytes = uint64_t(64) << 20;
/// ...and beyond that at most this many times the bytes stored. Real DAG data compresses
/// 2-10 times; a frame that declares more is a decompression bomb, refused before a byte
/// is allocated.
constexpr uint64_t kMaxSectionRatio = 1024;

/// Reads a section whose size the caller already knows from counts it validated
/// (`expectedSize`): the size must match, and a compressed section must declare and
/// decompress to exactly that many bytes within the ratio above, so no allocation
/// exceeds what the counts and the stored bytes allow.
/// `storage` receives decompressed bytes; the returned pointer is valid while `r`'s data
/// and `storage` live. FormatError through `r` otherwise.
const uint8_t* readSection(ByteReader& r, bool zstd, uint64_t expectedSize, const char* what,
                           std::vector<uint8_t>& storage);

}  // namespace cpvs
