#include "io/container.h"

#include <xxhash.h>
#include <zstd.h>

#include <algorithm>
#include <thread>

namespace cpvs {

void beginContainer(ByteWriter& w, const ContainerKind& kind, uint32_t flags) {
  w.raw(kind.magic, 4);
  w.put<uint32_t>(kind.version);
  w.put<uint32_t>(flags);
}

std::vector<uint8_t> sealContainer(ByteWriter&& w) {
  w.put<uint64_t>(XXH3_64bits(w.bytes.data(), w.bytes.size()));
  return std::move(w.bytes);
}

ByteReader openContainer(const uint8_t* data, size_t size, const std::string& source, const ContainerKind& kind,
                         uint32_t knownFlags, uint32_t& flags, uint32_t& version) {
  const std::string noun = kind.noun;
  ByteReader r(data, size, source);
  if (std::memcmp(r.take(4, "magic number"), kind.magic, 4) != 0) r.fail("not a " + noun + " (bad magic number)");
  version = r.get<uint32_t>("header");
  if (version < kind.minVersion || version > kind.version)
    r.fail(noun + " format version " + std::to_string(version) + " is not supported (this build reads version" +
           (kind.minVersion == kind.version ? " " + std::to_string(kind.version)
                                            : "s " + std::to_string(kind.minVersion) + " to " + std::to_string(kind.version)) +
           ")");
  if (size < r.pos() + 8) r.fail("truncated: no room for the checksum");
  uint64_t stored;
  std::memcpy(&stored, data + size - 8, 8);
  if (XXH3_64bits(data, size - 8) != stored) r.fail("checksum mismatch: the " + noun + " is corrupted or truncated");
  ByteReader body(data, size - 8, source);
  body.take(8, "header");
  flags = body.get<uint32_t>("header");
  if (flags & ~knownFlags) body.fail("unknown flags " + std::to_string(flags));
  return body;
}

void writeSection(ByteWriter& w, const std::vector<uint8_t>& bytes, bool zstd) {
  w.put<uint64_t>(bytes.size());
  if (!zstd) {
    w.put<uint64_t>(bytes.size());
    w.raw(bytes.data(), bytes.size());
    return;
  }
  // zstd's own workers compress a large section's jobs in parallel. Its output does not
  // depend on how many workers there are, as long as there is one (0 is another format
  // of the same data): the bytes are the same on every machine. One context per thread,
  // kept, so that its workers are started once.
  struct Context {
    ZSTD_CCtx* c = ZSTD_createCCtx();
    Context() {
      CPVS_CHECK(c != nullptr);
      ZSTD_CCtx_setParameter(c, ZSTD_c_compressionLevel, 9);
      const unsigned cores = std::thread::hardware_concurrency();
      ZSTD_CCtx_setParameter(c, ZSTD_c_nbWorkers, int(std::clamp(cores, 1u, 16u)));
    }
    ~Context() { ZSTD_freeCCtx(c); }
  };
  thread_local Context context;
  // zstd cuts its jobs at four windows (32 MiB at level 9): a section below a few of
  // those was one or two jobs, and a core waited. Below 128 MiB, four jobs (at least
  // 1 MiB, zstd's least here) keep both workers busy; each cut loses some of the window,
  // so not more (the peer's city at 16K, a 24 MB DAG: write 0.92 -> 0.83 s for 0.27 %
  // more bytes; jobs of 1 MiB would give 1.8 %). The job size depends on the section's
  // size only: the same bytes on every machine.
  constexpr size_t kFewJobsBelow = size_t(128) << 20, kLeastJob = size_t(1) << 20;
  const size_t job = bytes.size() < kFewJobsBelow ? std::max(kLeastJob, bytes.size() / 4) : 0;  // 0: zstd's own
  ZSTD_CCtx_setParameter(context.c, ZSTD_c_jobSize, int(job));
  std::vector<uint8_t> packed(ZSTD_compressBound(bytes.size()));
  const size_t n = ZSTD_compress2(context.c, packed.data(), packed.size(), bytes.data(), bytes.size());
  CPVS_CHECK(!ZSTD_isError(n));
  w.put<uint64_t>(n);
  w.raw(packed.data(), n);
}

const uint8_t* readSection(ByteReader& r, bool zstd, uint64_t expectedSize, const char* what,
                           std::vector<uint8_t>& storage) {
  const std::string name = what;
  const uint64_t size = r.get<uint64_t>(what);
  const uint64_t storedSize = r.get<uint64_t>(what);
  if (size != expectedSize)
    r.fail(name + " size " + std::to_string(size) + " does not match the counts before it (" +
           std::to_string(expectedSize) + ")");
  if (storedSize > r.remaining())
    r.fail(name + " is " + std::to_string(r.remaining()) + " bytes, the header says " + std::to_string(storedSize));
  const uint8_t* stored = r.take(storedSize, what);
  if (!zstd) {
    if (storedSize != size) r.fail(name + " size does not match");
    return stored;
  }
  // The frame must declare the size the counts allow before anything is allocated.
  const unsigned long long content = ZSTD_getFrameContentSize(stored, storedSize);
  if (content == ZSTD_CONTENTSIZE_ERROR || content == ZSTD_CONTENTSIZE_UNKNOWN || content != size)
    r.fail("compressed " + name + " is damaged");
  if (size > kSectionAlwaysAllowedBytes && size / kMaxSectionRatio > storedSize)
    r.fail("compressed " + name + " claims " + std::to_string(size) + " bytes from " + std::to_string(storedSize) +
           ": more than " + std::to_string(kMaxSectionRatio) + " times its size, refused");
  storage.resize(size);
  const size_t n = ZSTD_decompress(storage.data(), storage.size(), stored, storedSize);
  if (ZSTD_isError(n) || n != size) r.fail("compressed " + name + " is damaged");
  return storage.data();
}

}  // namespace cpvs
