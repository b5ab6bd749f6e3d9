// The sub-DAG transfer format: round trips, and every kind of damage a merge must never
// see is rejected with a message (truncation, bit flips, wrong order, foreign tiles).
#include <gtest/gtest.h>

#include "cpvs/base/error.h"
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

}  // namespace
}  // namespace cpvs
