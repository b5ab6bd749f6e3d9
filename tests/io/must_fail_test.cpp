// Damage that only a structural check can catch: each case corrupts one field of a valid
// .cpvs or sub-DAG, then recomputes the checksum so that the reader's own validators (not
// the checksum) must reject it, and expects that validator's message. The fuzzer reaches
// the same checks at random; this table reaches each of them on every run.
#include <gtest/gtest.h>
#include <xxhash.h>

#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "cpvs/base/error.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/io/sub_dag_file.h"
#include "dag_testing.h"

namespace cpvs {
namespace {

using Bytes = std::vector<uint8_t>;

template <class T>
T get(const Bytes& b, size_t at) {
  T v;
  std::memcpy(&v, b.data() + at, sizeof(T));
  return v;
}
template <class T>
void put(Bytes& b, size_t at, T v) {
  std::memcpy(b.data() + at, &v, sizeof(T));
}

// What a writer would have computed for the damaged bytes.
void resealChecksum(Bytes& b) { put<uint64_t>(b, b.size() - 8, XXH3_64bits(b.data(), b.size() - 8)); }

struct Case {
  const char* name;
  std::function<void(Bytes&)> damage;
  const char* message;  // a part of the InputError's message
};

std::string messageOf(const std::function<void(const Bytes&)>& decode, const Bytes& bytes) {
  try {
    decode(bytes);
  } catch (const FormatError& e) {
    return e.what();
  } catch (const InputError& e) {
    return std::string("(an InputError that is not a FormatError) ") + e.what();
  }
  return "(accepted)";
}

void expectEveryCaseRejected(const Bytes& valid, const std::vector<Case>& cases,
                             const std::function<void(const Bytes&)>& decode) {
  ASSERT_EQ(messageOf(decode, valid), "(accepted)");
  for (const Case& c : cases) {
    Bytes bad = valid;
    c.damage(bad);
    resealChecksum(bad);
    const std::string got = messageOf(decode, bad);
    EXPECT_TRUE(got.find(c.message) != std::string::npos && got.find("(an InputError") == std::string::npos)
        << c.name << ": got \"" << got << "\"";
  }
}

CpvsArtifact sampleArtifact() {
  TexelSlices d = testing::syntheticSlices(64, true, 9);
  CpvsArtifact art;
  art.dag = testing::buildTiled(d, 6, 6, UndefinedRule::New, true, CompressMode::TopDown, HashKind::Xxh3);
  art.grid.frame = LightFrame::fromDirection({0.3, -1, 0.2});
  art.grid.log2Resolution = 6;
  art.grid.extent = 10;
  art.grid.depthExtent = 5;
  art.options.log2TileSize = 6;
  art.sceneHash = Hash128{1, 2};
  return art;
}

// Byte offsets of the .cpvs header (cpvs_file.h), version 1.
constexpr size_t kDir = 12, kExtent = 132, kLog2R = 148, kOptions = 152, kTile = 160, kRootCode = 180,
                 kRootIndex = 184, kLevelCount = 188, kLeafCount = 192, kLevelSizes = 200;

TEST(MustFail, CpvsFieldsDamagedBehindAValidChecksum) {
  const CpvsArtifact art = sampleArtifact();
  const Bytes valid = encodeCpvs(art, false);
  const int levels = int(art.dag.levels.size());
  const size_t payloadSize = kLevelSizes + 16 * size_t(levels), payload = payloadSize + 16;
  const uint64_t leaves = art.dag.leaves.size();
  // Level 0 starts after the leaves: its codes, padded to 4 bytes, then its child indices.
  const size_t level0Codes = payload + 8 * leaves;
  const size_t level0Children = level0Codes + ((art.dag.levels[0].size() * 2 + 3) & ~size_t(3));
  ASSERT_GT(art.dag.levels[0].children.size(), 0u);

  const std::vector<Case> cases{
      {"flags", [](Bytes& b) { put<uint32_t>(b, 8, 6); }, "unknown flags 6"},
      {"light direction", [](Bytes& b) { put<double>(b, kDir, get<double>(b, kDir) * 2); }, "not a unit vector"},
      {"non-finite extent", [](Bytes& b) { put<double>(b, kExtent, 1.0 / 0.0); }, "non-finite"},
      {"negative extent", [](Bytes& b) { put<double>(b, kExtent, -1.0); }, "not positive"},
      {"resolution", [](Bytes& b) { put<int32_t>(b, kLog2R, 30); }, "resolution 2^30 is out of range"},
      {"closed mode", [](Bytes& b) { b[kOptions] = 3; }, "options hold an unknown value"},
      {"hash kind", [](Bytes& b) { b[kOptions + 5] = 2; }, "options hold an unknown value"},
      {"renderer", [](Bytes& b) { b[kOptions + 6] = 2; }, "options hold an unknown value"},
      {"reserved byte", [](Bytes& b) { b[kOptions + 7] = 1; }, "options hold an unknown value"},
      {"tile size", [](Bytes& b) { put<int32_t>(b, kTile, 2); }, "tile size 2^2 is out of range"},
      {"root code", [](Bytes& b) { put<uint32_t>(b, kRootCode, 3); }, "root reference is invalid"},
      {"root index", [](Bytes& b) { put<uint32_t>(b, kRootIndex, 1000000); }, "root reference is invalid"},
      {"level count", [](Bytes& b) { put<uint32_t>(b, kLevelCount, get<uint32_t>(b, kLevelCount) + 1); }, "levels where"},
      {"leaf count", [](Bytes& b) { put<uint64_t>(b, kLeafCount, uint64_t(1) << 40); }, "leaf count is out of range"},
      {"child count", [](Bytes& b) { put<uint64_t>(b, kLevelSizes + 8, 9 * get<uint64_t>(b, kLevelSizes)); },
       "sizes are out of range"},
      {"more child references than 32 bits hold (R24)",
       [](Bytes& b) {
         put<uint64_t>(b, kLevelSizes, uint64_t(1) << 31);
         put<uint64_t>(b, kLevelSizes + 8, uint64_t(1) << 33);
       },
       "sizes are out of range"},
      {"payload size", [=](Bytes& b) { put<uint64_t>(b, payloadSize, get<uint64_t>(b, payloadSize) + 8); },
       "does not match the counts"},
      {"child code 3", [=](Bytes& b) { put<uint16_t>(b, level0Codes, uint16_t(get<uint16_t>(b, level0Codes) | 3)); },
       "invalid child code"},
      {"child index", [=](Bytes& b) { put<uint32_t>(b, level0Children, uint32_t(leaves)); }, "out of range"},
      {"trailing bytes", [](Bytes& b) { b.insert(b.end() - 8, {0, 0, 0, 0}); }, "unexpected bytes after the payload"},
      {"magic", [](Bytes& b) { b[0] = 'X'; }, "not a .cpvs file"},
      {"version", [](Bytes& b) { put<uint32_t>(b, 4, 9); }, "format version 9 is not supported"},
  };
  expectEveryCaseRejected(valid, cases, [](const Bytes& b) { decodeCpvs(b.data(), b.size(), "damaged.cpvs"); });
}

// The renderer is the byte that files written before it held as 0: they read as Embree's,
// which made them.
TEST(CpvsHeader, RendererRoundTripsAndZeroIsEmbree) {
  CpvsArtifact art = sampleArtifact();
  for (Renderer r : {Renderer::Raster, Renderer::Embree}) {
    art.options.renderer = r;
    const Bytes bytes = encodeCpvs(art, false);
    EXPECT_EQ(bytes[kOptions + 6], uint8_t(r));
    EXPECT_EQ(decodeCpvs(bytes.data(), bytes.size(), "r.cpvs").options.renderer, r);
  }
  static_assert(int(Renderer::Embree) == 0);
}

// Byte offsets of the sub-DAG header (sub_dag_file.h).
constexpr size_t kSubLog2R = 12, kSubLog2Root = 16, kRootCount = 20, kRoots = 28;

TEST(MustFail, SubDagFieldsDamagedBehindAValidChecksum) {
  TexelSlices d = testing::syntheticSlices(64, true, 5);
  const Dag tile = testing::buildTile(d, 6, 5, 0, 1, UndefinedRule::New, true, CompressMode::TopDown, HashKind::Xxh3);
  ASSERT_EQ(tile.roots.size(), 2u);
  ASSERT_GE(tile.leaves.size(), 2u);
  const Bytes valid = encodeSubDag(tile, false);
  const size_t levelTable = kRoots + 16 * tile.roots.size();
  const size_t payload = levelTable + 4 + 8 + 16 * tile.levels.size() + 16;

  const std::vector<Case> cases{
      {"root size above the grid", [](Bytes& b) { put<int32_t>(b, kSubLog2Root, 7); }, "out of range"},
      {"resolution", [](Bytes& b) { put<int32_t>(b, kSubLog2R, 21); }, "out of range"},
      {"root count", [](Bytes& b) { put<uint64_t>(b, kRootCount, uint64_t(1) << 40); }, "exceeds the data"},
      {"root order", [](Bytes& b) { put<uint64_t>(b, kRoots + 16, get<uint64_t>(b, kRoots)); }, "out-of-order position"},
      {"root outside the grid", [](Bytes& b) { put<uint64_t>(b, kRoots, rootKey(5, 0, 0)); }, "invalid or out-of-order"},
      {"root code", [](Bytes& b) { put<uint32_t>(b, kRoots + 8, 3); }, "root 0 has an invalid reference"},
      {"root index", [](Bytes& b) { put<uint32_t>(b, kRoots + 12, 1u << 30); }, "root 0 has an invalid reference"},
      {"leaves out of canonical order",
       [=](Bytes& b) {
         const uint64_t first = get<uint64_t>(b, payload), second = get<uint64_t>(b, payload + 8);
         put<uint64_t>(b, payload, second);
         put<uint64_t>(b, payload + 8, first);
       },
       "not in canonical order"},
      {"magic", [](Bytes& b) { b[3] = 'S'; }, "not a sub-DAG"},
  };
  expectEveryCaseRejected(valid, cases,
                          [](const Bytes& b) { decodeSubDag(b.data(), b.size(), "tile", true, HashKind::Xxh3); });
}

}  // namespace
}  // namespace cpvs
