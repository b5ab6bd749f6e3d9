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
#include "cpvs/base/file.h"
#include "cpvs/dag/packed_dag.h"
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

// Byte offsets of the .cpvs header (cpvs_file.h), the same in versions 1 to 3.
constexpr size_t kDir = 12, kExtent = 132, kLog2R = 148, kOptions = 152, kTile = 160;
// Version 3: the receiver declaration (kind, PCF, reserved, hash).
constexpr size_t kReceivers = 180, kReceiverHash = 188, kPlanBytes = 204;
// Version 3 (with no plan): the word count, the section's size and stored size, then the packed words.
constexpr size_t kWordCount = 208, kSectionSize = 216, kWords = 232;
// Version 1: the root, then the level table.
constexpr size_t kRootCode = 180, kRootIndex = 184, kLevelCount = 188, kLeafCount = 192, kLevelSizes = 200;

// The cases every version shares: the header before the DAG, the container around it.
std::vector<Case> headerCases() {
  return {
      {"flags", [](Bytes& b) { put<uint32_t>(b, 8, 6); }, "unknown flags 6"},
      {"light direction", [](Bytes& b) { put<double>(b, kDir, get<double>(b, kDir) * 2); }, "not a unit vector"},
      {"non-finite extent", [](Bytes& b) { put<double>(b, kExtent, 1.0 / 0.0); }, "non-finite"},
      {"negative extent", [](Bytes& b) { put<double>(b, kExtent, -1.0); }, "not positive"},
      {"resolution", [](Bytes& b) { put<int32_t>(b, kLog2R, 30); }, "resolution 2^30 is out of range"},
      {"depth shift beyond the resolution", [](Bytes& b) { put<int32_t>(b, kLog2R, 6 | 7 << 8); }, "names no grid"},
      {"negative resolution field", [](Bytes& b) { put<int32_t>(b, kLog2R, -1); }, "names no grid"},
      {"resolution out of range with a depth shift", [](Bytes& b) { put<int32_t>(b, kLog2R, 60 | 1 << 8); },
       "resolution 2^60 is out of range"},
      {"closed mode", [](Bytes& b) { b[kOptions] = 3; }, "options hold an unknown value"},
      {"hash kind", [](Bytes& b) { b[kOptions + 5] = 2; }, "options hold an unknown value"},
      {"renderer", [](Bytes& b) { b[kOptions + 6] = 2; }, "options hold an unknown value"},
      {"reserved byte", [](Bytes& b) { b[kOptions + 7] = 1; }, "options hold an unknown value"},
      {"tile size", [](Bytes& b) { put<int32_t>(b, kTile, 2); }, "tile size 2^2 is out of range"},
      {"trailing bytes", [](Bytes& b) { b.insert(b.end() - 8, {0, 0, 0, 0}); }, "unexpected bytes after the payload"},
      {"magic", [](Bytes& b) { b[0] = 'X'; }, "not a .cpvs file"},
      {"version", [](Bytes& b) { put<uint32_t>(b, 4, 9); }, "format version 9 is not supported (this build reads versions 1 to 4)"},
  };
}

const auto decodeDamaged = [](const Bytes& b) { decodeCpvs(b.data(), b.size(), "damaged.cpvs"); };

TEST(MustFail, CpvsFieldsDamagedBehindAValidChecksum) {
  const CpvsArtifact art = sampleArtifact();
  const Bytes valid = encodeCpvs(art, false);
  ASSERT_EQ(get<uint32_t>(valid, 4), 3u);
  const PackedDag packed(art.dag);
  const PackedHeader& h = packed.header();
  const uint32_t L = h.internalLevels;
  ASSERT_GE(L, 2u);
  ASSERT_EQ(get<uint64_t>(valid, kWordCount), packed.words().size());
  auto word = [](uint32_t k) { return kWords + 4 * size_t(k); };
  // Field k of the packed header, and the first child of the first node of a level.
  auto field = [&](size_t offset) { return kWords + offset; };
  // A pool this small names every child by one half-word: a node's codes in the low half of
  // its first word, its first reference in the high half.
  ASSERT_EQ(h.layoutVersion, kPackedLayoutVersion);
  ASSERT_EQ(h.wideRefs, 0u);
  ASSERT_NE(packed.words()[h.levelWord[0]] & 0xAAAA, 0u);  // the first nodes have a kRef child
  ASSERT_NE(packed.words()[h.levelWord[1]] & 0xAAAA, 0u);

  std::vector<Case> cases = headerCases();
  const std::vector<Case> packedCases{
      {"plan size", [](Bytes& b) { put<uint32_t>(b, kPlanBytes, 1u << 21); }, "the plan's size 2097152 is invalid"},
      {"receiver kind", [](Bytes& b) { b[kReceivers] = 5; }, "the receiver declaration holds an unknown value"},
      {"receiver reserved byte", [](Bytes& b) { b[kReceivers + 7] = 1; }, "the receiver declaration holds an unknown value"},
      {"receiver PCF for everywhere", [](Bytes& b) { b[kReceivers + 1] = 9; }, "the receiver declaration is inconsistent"},
      {"receiver hash for everywhere", [](Bytes& b) { b[kReceiverHash] = 1; }, "the receiver declaration is inconsistent"},
      {"surfaces without a hash", [](Bytes& b) { b[kReceivers] = 1, b[kReceivers + 1] = 9; }, "the receiver declaration is inconsistent"},
      {"surfaces with an even PCF", [](Bytes& b) { b[kReceivers] = 1, b[kReceivers + 1] = 4, b[kReceiverHash] = 1; },
       "the receiver declaration is inconsistent"},
      {"word count", [](Bytes& b) { put<uint64_t>(b, kWordCount, 3); }, "packed DAG word count 3 is invalid"},
      {"word count beyond 32 bits", [](Bytes& b) { put<uint64_t>(b, kWordCount, uint64_t(1) << 40); }, "is invalid"},
      {"section size", [](Bytes& b) { put<uint64_t>(b, kSectionSize, get<uint64_t>(b, kSectionSize) + 4); },
       "does not match the counts"},
      {"layout version", [=](Bytes& b) { put<uint32_t>(b, word(0), 7); }, "layout version 7 is not supported"},
      {"packed resolution", [=](Bytes& b) { put<uint32_t>(b, word(1), 7); }, "of resolution 2^7, the grid of 2^6"},
      {"level count", [=](Bytes& b) { put<uint32_t>(b, word(2), L + 1); }, "level counts do not match"},
      {"grid levels", [=](Bytes& b) { put<uint32_t>(b, word(3), 2); }, "level counts do not match"},
      {"header word count", [=](Bytes& b) { put<uint32_t>(b, field(offsetof(PackedHeader, wordCount)), 1u << 30); },
       "the header counts 1073741824 words"},
      {"odd leaf word",
       [=](Bytes& b) {
         put<uint32_t>(b, field(offsetof(PackedHeader, leafWord)), h.leafWord + 1);
         put<uint32_t>(b, field(offsetof(PackedHeader, leafCount)), h.leafCount);
       },
       "the leaves do not end the array"},
      {"root code", [=](Bytes& b) { put<uint32_t>(b, field(offsetof(PackedHeader, rootCode)), 3); }, "root code is invalid"},
      {"root word", [=](Bytes& b) { put<uint32_t>(b, field(offsetof(PackedHeader, rootWord)), h.rootWord + 1); },
       "not a node of the level below"},
      {"level start", [=](Bytes& b) { put<uint32_t>(b, field(offsetof(PackedHeader, levelWord)) + 4 * (L - 1), h.levelWord[L - 1] + 2); },
       "does not start where the one above ends"},
      {"level beyond the root", [=](Bytes& b) { put<uint32_t>(b, field(offsetof(PackedHeader, levelNodes)) + 4 * L, 1); },
       "a level beyond the root is not empty"},
      {"child code 3", [=](Bytes& b) { put<uint32_t>(b, word(h.levelWord[0]), get<uint32_t>(b, word(h.levelWord[0])) | 3); },
       "invalid child code"},
      {"leaf index", [=](Bytes& b) { put<uint32_t>(b, word(h.levelWord[0]), get<uint32_t>(b, word(h.levelWord[0])) | 0xFFFF0000u); },
       "a child offset is not a leaf"},
      {"node offset inside a node",
       [=](Bytes& b) { put<uint32_t>(b, word(h.levelWord[1]), (get<uint32_t>(b, word(h.levelWord[1])) & 0xFFFFu) | 1u << 16); },
       "not a node of the level below"},
      {"wide references beyond the levels", [=](Bytes& b) { put<uint32_t>(b, field(offsetof(PackedHeader, wideRefs)), 1u << L); },
       "layout version 3 does not name children as its header says"},
      {"wide references the sizes do not give", [=](Bytes& b) { put<uint32_t>(b, field(offsetof(PackedHeader, wideRefs)), 1u << (L - 1)); },
       "packed DAG: "},
      {"layout version 2 (a leaf index per half-word, a word per node reference)", [=](Bytes& b) { put<uint32_t>(b, word(0), 2); },
       "leaf references 0 do not fit"},
      {"layout version 1", [=](Bytes& b) { put<uint32_t>(b, word(0), 1); }, "packed DAG: "},
      {"pointer grid", [=](Bytes& b) { put<uint32_t>(b, word(h.gridWord), get<uint32_t>(b, word(h.gridWord)) ^ 1); },
       "the pointer grid, the reference widths or the padding do not match"},
      {"reserved word", [=](Bytes& b) { put<uint32_t>(b, field(offsetof(PackedHeader, reserved)), 1); },
       "the pointer grid, the reference widths or the padding do not match"},
  };
  cases.insert(cases.end(), packedCases.begin(), packedCases.end());
  expectEveryCaseRejected(valid, cases, decodeDamaged);
}

// A version 1 file (the reader goes on reading them): one written by the last build of
// version 1 (city:3:7, 256^3, sun at 40/30 degrees, no zstd) reads, with the DAG size that
// build printed, and packs to the words version 2 writes; then its level table damaged.
TEST(MustFail, CpvsVersion1FieldsDamagedBehindAValidChecksum) {
  const Bytes valid = readFile(CPVS_SOURCE_DIR "/tests/io/data/city-256-v1.cpvs");
  ASSERT_EQ(get<uint32_t>(valid, 4), 1u);
  const CpvsArtifact art = decodeCpvs(valid.data(), valid.size(), "v1.cpvs");
  EXPECT_EQ(art.grid.log2Resolution, 8);
  // 45,236 bytes as the version 1 build printed it (packed layout 1); 34,348 in layout 2
  // (level 0 names its leaves by 16-bit index); fewer in today's half-words.
  EXPECT_EQ(art.dag.bytes(1), 45236u);
  EXPECT_EQ(art.dag.bytes(2), 34348u);
  EXPECT_EQ(art.dag.bytes(), 25514u);
  EXPECT_EQ(art.packed.bytes(), art.dag.bytes());
  EXPECT_EQ(art.packed.words(), PackedDag(art.dag).words());
  const int levels = int(art.dag.levels.size());
  const size_t payloadSize = kLevelSizes + 16 * size_t(levels), payload = payloadSize + 16;
  const uint64_t leaves = art.dag.leaves.size();
  // Level 0 starts after the leaves: its codes, padded to 4 bytes, then its child indices.
  const size_t level0Codes = payload + 8 * leaves;
  const size_t level0Children = level0Codes + ((art.dag.levels[0].size() * 2 + 3) & ~size_t(3));
  ASSERT_GT(art.dag.levels[0].children.size(), 0u);

  std::vector<Case> cases = headerCases();
  const std::vector<Case> levelCases{
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
  };
  cases.insert(cases.end(), levelCases.begin(), levelCases.end());
  expectEveryCaseRejected(valid, cases, decodeDamaged);
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

// A grid with fewer depth slices keeps them: its depth shift is the resolution field's
// second byte (a reader before them refuses the resolution); a cubic grid's field is as before.
TEST(CpvsHeader, DepthSlicesRoundTripInTheResolutionField) {
  CpvsArtifact art = sampleArtifact();
  EXPECT_EQ(get<int32_t>(encodeCpvs(art, false), kLog2R), 6);
  for (uint32_t slices : {1u, 16u, 32u}) {
    art.grid.depthSlices = slices;
    const Bytes bytes = encodeCpvs(art, false);
    EXPECT_EQ(get<int32_t>(bytes, kLog2R), 6 | art.grid.depthShift() << 8);
    const CpvsArtifact back = decodeCpvs(bytes.data(), bytes.size(), "d.cpvs");
    EXPECT_EQ(back.grid.depthSlices, slices);
    EXPECT_EQ(back.grid.log2Resolution, 6);
  }
}

// The receiver declaration round-trips; a version 2 file (before it) reads as baked for
// receivers everywhere, with its DAG intact.
TEST(CpvsHeader, ReceiversRoundTripAndVersion2ReadsAsEverywhere) {
  CpvsArtifact art = sampleArtifact();
  art.options.receivers = ReceiverKind::Volume;
  art.options.receiverPcf = 5;
  art.receiverHash = Hash128{7, 8};
  const Bytes bytes = encodeCpvs(art, false);
  EXPECT_EQ(bytes[kReceivers], uint8_t(ReceiverKind::Volume));
  const CpvsArtifact back = decodeCpvs(bytes.data(), bytes.size(), "r.cpvs");
  EXPECT_EQ(back.options, art.options);
  EXPECT_EQ(back.receiverHash, art.receiverHash);
  art.plan = R"({"scene": "sample", "passes": []})";
  const Bytes withPlan = encodeCpvs(art, false);
  EXPECT_EQ(decodeCpvs(withPlan.data(), withPlan.size(), "p.cpvs").plan, art.plan);
  art.plan = "\xff\xfe";
  const Bytes badPlan = encodeCpvs(art, false);
  EXPECT_THROW(decodeCpvs(badPlan.data(), badPlan.size(), "p.cpvs"), FormatError);

  // city:3:7, 256^3, sun at 40/30 degrees, zstd, written by the version 2 build.
  const Bytes v2 = readFile(CPVS_SOURCE_DIR "/tests/io/data/city-256-v2.cpvs");
  ASSERT_EQ(get<uint32_t>(v2, 4), 2u);
  const CpvsArtifact old = decodeCpvs(v2.data(), v2.size(), "v2.cpvs");
  EXPECT_EQ(old.formatVersion, 2u);
  EXPECT_EQ(old.options.receivers, ReceiverKind::Everywhere);
  EXPECT_EQ(old.receiverHash, Hash128{});
  // Its words are packed layout 1 (a word per code and per reference, level 0's leaves by
  // word offset), 45,236 bytes as the version 2 build printed it: they read, are packed
  // again in today's layout, and answer every voxel as the DAG they hold.
  const std::vector<uint32_t> layout1 = packPool(old.dag.leaves, old.dag.levels, {{8, old.dag.roots.front().ref}}, 1);
  EXPECT_EQ(layout1[0], 1u);
  EXPECT_EQ(old.dag.bytes(1), 45236u);
  EXPECT_EQ(old.packed.header().layoutVersion, kPackedLayoutVersion);
  EXPECT_EQ(old.packed.words(), PackedDag(old.dag).words());
  EXPECT_EQ(old.packed.bytes(), old.dag.bytes());
  EXPECT_LT(old.packed.bytes(), old.dag.bytes(2));
  for (uint64_t z = 0; z < 256; ++z)
    for (uint64_t y = 0; y < 256; ++y)
      for (uint64_t x = 0; x < 256; ++x)
        ASSERT_EQ(old.packed.voxelShadowed(x, y, z), dagVoxelShadowed(old.dag, x, y, z)) << x << "," << y << "," << z;
  // The same DAG in each layout reads back as itself.
  for (uint32_t version = 1; version <= kPackedLayoutVersion; ++version) {
    Dag back;
    const PackedDag read = PackedDag::fromWords(packPool(old.dag.leaves, old.dag.levels, {{8, old.dag.roots.front().ref}}, version), back);
    EXPECT_EQ(read.words(), old.packed.words()) << "layout " << version;
    EXPECT_EQ(back.levels.size(), old.dag.levels.size());
    for (size_t l = 0; l < back.levels.size(); ++l) {
      EXPECT_EQ(back.levels[l].codes, old.dag.levels[l].codes) << "layout " << version;
      EXPECT_EQ(back.levels[l].children, old.dag.levels[l].children) << "layout " << version;
    }
  }
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
