// The sub-DAG transfer format: round trips, and every kind of damage a merge must never
// see is rejected with a message (truncation, bit flips, wrong order, foreign tiles).
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <xxhash.h>

#include "cpvs/base/error.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/io/sub_dag_file.h"
#include "dag_testing.h"

namespace cpvs {
namespace {

Dag sampleTile(uint32_t tx, uint32_t ty, CompressMode mode = CompressMode::TopDown) {
  TexelSlices d = testing::syntheticSlices(64, true, 5);
  return testing::buildTile(d, 6, 5, tx, ty, UndefinedRule::New, true, mode, HashKind::Xxh3);
}

std::string messageOf(const std::vector<uint8_t>& bytes, bool canonical = true) {
  try {
    decodeSubDag(bytes.data(), bytes.size(), "tile", canonical, HashKind::Xxh3);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(SubDagFile, RoundTripsWithHashes) {
  for (bool zstd : {true, false}) {
    Dag tile = sampleTile(1, 0);
    const std::vector<uint8_t> bytes = encodeSubDag(tile, zstd);
    Dag back = decodeSubDag(bytes.data(), bytes.size(), "tile", true, HashKind::Xxh3);
    testing::expectSameDag(tile, back);
    EXPECT_EQ(back.leafHashes, tile.leafHashes);
    EXPECT_EQ(back.levelHashes, tile.levelHashes);
    EXPECT_EQ(back.log2RootSize, 5);
    EXPECT_NO_THROW(checkTileRoots(back, 1, 0, 5, "tile"));
  }
}

TEST(SubDagFile, RejectsTruncationAndEveryFlippedByte) {
  std::vector<uint8_t> bytes = encodeSubDag(sampleTile(0, 1), false);
  for (size_t n : {size_t(0), size_t(3), size_t(8), bytes.size() / 2, bytes.size() - 1}) {
    std::vector<uint8_t> cut(bytes.begin(), bytes.begin() + std::ptrdiff_t(n));
    EXPECT_NE(messageOf(cut), "") << "truncated to " << n;
  }
  // The checksum catches each of these; io/must_fail_test reaches the checks behind it.
  for (size_t i = 0; i < bytes.size(); ++i) {
    std::vector<uint8_t> bad = bytes;
    bad[i] ^= 0x10;
    EXPECT_NE(messageOf(bad), "") << "byte " << i;
  }
}

TEST(SubDagFile, RejectsLevelsOutOfCanonicalOrder) {
  Dag raw = sampleTile(1, 1, CompressMode::None);  // as inserted: not hash-sorted
  std::vector<uint8_t> bytes = encodeSubDag(raw);
  EXPECT_NE(messageOf(bytes, true).find("canonical order"), std::string::npos) << messageOf(bytes, true);
  EXPECT_EQ(messageOf(bytes, false), "") << "an uncompressed job accepts insertion order";
}

TEST(SubDagFile, RejectsAnotherTilesRoots) {
  Dag tile = sampleTile(1, 0);
  EXPECT_THROW(checkTileRoots(tile, 0, 1, 5, "tile"), InputError);
  EXPECT_THROW(checkTileRoots(tile, 1, 0, 4, "tile"), InputError);
  Dag missing = tile;
  missing.roots.pop_back();
  EXPECT_THROW(checkTileRoots(missing, 1, 0, 5, "tile"), InputError);
}


// R1: a sub-DAG whose level table asks for 4 GiB of leaves and whose zstd frame declares
// them, in a handful of bytes (one RLE block). The reader must refuse it before it
// allocates: a child process with 512 MiB of address space decodes it and must see an
// InputError, not bad_alloc or the OOM killer. And a .cpvs whose packed section does the same.
std::vector<uint8_t> bomb(bool cpvs) {
  std::vector<uint8_t> b;
  auto put32 = [&](uint32_t v) { b.insert(b.end(), (uint8_t*)&v, (uint8_t*)&v + 4); };
  auto put64 = [&](uint64_t v) { b.insert(b.end(), (uint8_t*)&v, (uint8_t*)&v + 8); };
  const uint64_t claimed = uint64_t(1) << 32;
  if (cpvs) {
    // A valid header from a real file, then a word count of 2^30 (4 GiB).
    CpvsArtifact art;
    art.dag.reset(6, 6);
    art.dag.roots.push_back({0, {kLit, 0}});
    art.grid.frame = LightFrame::fromDirection({0.3, -1, 0.2});
    art.grid.log2Resolution = 6;
    const std::vector<uint8_t> valid = encodeCpvs(art, true);
    b.assign(valid.begin(), valid.begin() + 208);
    put64(claimed / 4);
  } else {
    b.insert(b.end(), {'C', 'P', 'V', 'T'});
    put32(1);  // version
    put32(1);  // zstd
    put32(6);  // log2R
    put32(5);  // log2 root size
    put64(0);  // no roots
    put32(3);  // levels of a 2^5 root
    put64(claimed / 8);  // leaves
    for (int l = 0; l < 3; ++l) put64(0), put64(0);
  }
  put64(claimed);  // the section's size, as the counts require
  const uint8_t frame[] = {0x28, 0xB5, 0x2F, 0xFD, 0xE0, 0, 0, 0, 0, 1, 0, 0, 0, 0x0B, 0, 0, 0x07};
  put64(sizeof frame);
  b.insert(b.end(), frame, frame + sizeof frame);
  const uint64_t sum = XXH3_64bits(b.data(), b.size());
  put64(sum);
  return b;
}

// Under AddressSanitizer an address-space limit cannot stand in for "allocated nothing
// big": the sanitizer's shadow is mapped before the limit is set, so its allocator's next
// mapping fails whatever the decoder asks for. There the allocator's own hook records the
// largest single allocation instead, and the child reports it.
#if defined(__SANITIZE_ADDRESS__)
extern "C" int __sanitizer_install_malloc_and_free_hooks(void (*)(const volatile void*, size_t),
                                                         void (*)(const volatile void*));
size_t largestAllocation = 0;
void recordAllocation(const volatile void*, size_t size) {
  if (size > largestAllocation) largestAllocation = size;
}
void ignoreFree(const volatile void*) {}
void limitAllocations() {
  // The runtime installs nothing unless both hooks are given.
  if (!__sanitizer_install_malloc_and_free_hooks(recordAllocation, ignoreFree)) _exit(6);
}
bool allocatedTooMuch() { return largestAllocation > (size_t(256) << 20); }
#else
void limitAllocations() {
  rlimit limit{512u << 20, 512u << 20};
  setrlimit(RLIMIT_AS, &limit);
}
bool allocatedTooMuch() { return false; }  // the limit turned it into std::bad_alloc
#endif

TEST(SubDagFile, DecompressionBombsAreRefusedBeforeAllocating) {
  for (bool cpvs : {false, true}) {
    const std::vector<uint8_t> bytes = bomb(cpvs);
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      limitAllocations();
      try {
        if (cpvs) decodeCpvs(bytes.data(), bytes.size(), "bomb.cpvs");
        else decodeSubDag(bytes.data(), bytes.size(), "bomb", true, HashKind::Xxh3);
      } catch (const InputError& e) {
        if (allocatedTooMuch()) _exit(4);
        _exit(std::string(e.what()).find("times its size, refused") != std::string::npos ? 0 : 3);
      } catch (const std::bad_alloc&) {
        _exit(4);
      }
      _exit(5);
    }
    int status = 0;
    ASSERT_EQ(waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFEXITED(status)) << (cpvs ? ".cpvs" : "sub-DAG") << ": killed by signal " << WTERMSIG(status);
    EXPECT_EQ(WEXITSTATUS(status), 0) << (cpvs ? ".cpvs" : "sub-DAG")
                                      << ": 3 another InputError, 4 allocated more than it may, 5 accepted, 6 no allocation hook";
  }
}

}  // namespace
}  // namespace cpvs
