// A DAG-MH bake against the CPVS of the same scene, grid and receivers: every voxel the
// receivers read answers alike, so do the receivers' filtered lookups, and exact shadow
// rays agree away from boundaries; the .dmh file round-trips and refuses damage.
#include <gtest/gtest.h>
#include <oneapi/tbb/task_arena.h>
#include <xxhash.h>

#include <cstring>
#include <random>

#include "cpvs/bake/bake_dag_mh.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/raster_slices.h"
#include "cpvs/base/error.h"
#include "cpvs/eval/surface_sampling.h"
#include "cpvs/eval/verify.h"
#include "cpvs/io/dmh_file.h"
#include "cpvs/io/dmh_tile_file.h"
#include "cpvs/query/dag_mh_query.h"
#include "cpvs/query/shadow_query.h"
#include "cpvs/scene/source.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

struct Case {
  std::string scene;  // a generator, or a path under the shared scenes
  Vec3 sun;
  ReceiverKind receivers;
  int pcf;
};

Scene openCase(const Case& c) {
  if (c.scene.find('/') == std::string::npos) return openScene(c.scene);
  const std::string shared = testing::sharedScenesDir();
  EXPECT_FALSE(shared.empty()) << "the shared scenes are beside the project after deploy/setup.sh";
  return openScene(shared + "/" + c.scene);
}

ReceiverDeclaration declarationOf(const Case& c) {
  ReceiverDeclaration d;
  d.kind = c.receivers;
  d.maxPcf = c.pcf;
  return d;
}

void PrintTo(const Case& c, std::ostream* os) {
  *os << c.scene << ", receivers " << optionName(c.receivers) << " PCF " << c.pcf;
}

class DagMhBake : public ::testing::TestWithParam<Case> {};

TEST_P(DagMhBake, AnswersWhatTheReceiversReadAsTheCpvs) {
  const Case& c = GetParam();
  const Scene scene = openCase(c);
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection(c.sun), 7);
  const ReceiverDeclaration receivers = declarationOf(c);
  BakeOptions options;
  CpvsArtifact cpvs = testing::localArtifact(scene, grid, options, receivers);
  const ShadowQuery reference(grid, PackedDag(cpvs.dag));
  const DagMh dag = bakeDagMh(scene, grid, options, receivers);
  ASSERT_NO_THROW(validateDagMh(dag, "bake"));
  const DagMhQuery query(grid, dag);

  // Every voxel the classification defines (what the receivers read, or everything).
  const BakeScene prepared(scene, grid, Renderer::Raster, 0, receivers);
  const uint32_t R = uint32_t(grid.resolution());
  TexelSlices slices;
  rasterTexelSlices(prepared.raster(), options.closed, options.exit, 0, 0, R, R, slices);
  prepared.receivers().freeIntervals(0, 0, R, R, slices);
  uint64_t compared = 0, wrong = 0;
  for (uint32_t y = 0; y < R; ++y)
    for (uint32_t x = 0; x < R; ++x) {
      const size_t i = size_t(y) * R + x;
      for (uint32_t k = 0; k < R; ++k) {
        if (k >= slices.firstUndefined[i] && k < slices.firstShadowed[i]) continue;
        ++compared;
        const VoxelCoord v{x, y, k};
        if (query.voxelShadowed(v) != reference.voxelShadowed(v) && ++wrong < 5)
          ADD_FAILURE() << "voxel " << x << "," << y << "," << k << ": DAG-MH " << query.voxelShadowed(v);
      }
    }
  EXPECT_EQ(wrong, 0u);
  EXPECT_GT(compared, uint64_t(R) * R);

  // The receivers' lookups, filtered: the same fractions wherever every voxel read is
  // defined (a filter beside a closed part reads its inside, which each resolves its own
  // way; so do binary lookups whose offset point lands inside one).
  const RayScene rays(scene, grid.origin);
  const auto samples = sampleReceivers(scene, rays, options.closed, grid.frame.dir, receivers, 20000, 5);
  auto defined = [&](const VoxelCoord& v) {
    if (v.x < 0 || v.y < 0 || v.x >= int64_t(R) || v.y >= int64_t(R) || v.z < 0) return true;
    const size_t i = size_t(v.y) * R + size_t(v.x);
    const int64_t k = std::min<int64_t>(v.z, R - 1);
    return k < int64_t(slices.firstUndefined[i]) || k >= int64_t(slices.firstShadowed[i]);
  };
  for (const int pcf : {1, 3, c.pcf}) {
    uint64_t same = 0, differ = 0;
    for (const SurfaceSample& s : samples) {
      const VoxelCoord v = reference.voxelOf(s.point, s.normal, pcf);
      bool all = true;
      for (int64_t dy = -pcf / 2; dy <= pcf / 2 && all; ++dy)
        for (int64_t dx = -pcf / 2; dx <= pcf / 2 && all; ++dx) all = defined({v.x + dx, v.y + dy, v.z});
      if (!all) continue;
      const bool equal = query.filtered(s.point, s.normal, pcf) == reference.filtered(s.point, s.normal, pcf);
      same += equal;
      differ += !equal;
    }
    EXPECT_EQ(differ, 0u) << "PCF " << pcf;
    EXPECT_GT(same, samples.size() / 4) << "PCF " << pcf;
  }
  // And exact shadow rays: no mismatch away from a shadow boundary.
  const VerifyResult r = verifyDagMhSamples(query, options.closed, rays, samples);
  EXPECT_GT(r.samples, 10000u);
  EXPECT_EQ(r.mismatchElsewhere, 0u);
}

TEST_P(DagMhBake, TheSameBytesOnOneThread) {
  const Case& c = GetParam();
  const Scene scene = openCase(c);
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection(c.sun), 9);
  const DagMh many = bakeDagMh(scene, grid, BakeOptions{}, declarationOf(c));
  tbb::task_arena one(1);
  const DagMh single = one.execute([&] { return bakeDagMh(scene, grid, BakeOptions{}, declarationOf(c)); });
  EXPECT_EQ(many.nodes, single.nodes);
  EXPECT_EQ(many.treelets, single.treelets);
  EXPECT_EQ(many.values.factors, single.values.factors);
}

INSTANTIATE_TEST_SUITE_P(
    Scenes, DagMhBake,
    ::testing::Values(Case{"city:6", {0.3, -1, 0.2}, ReceiverKind::Everywhere, 9},
                      Case{"city:6", {0.3, -1, 0.2}, ReceiverKind::Surfaces, 9},
                      Case{"landscape:32", {0.7, -0.3, -0.2}, ReceiverKind::Surfaces, 3},
                      Case{"openarena/oa_shouse.obj", {-0.31, -1, 0.22}, ReceiverKind::Surfaces, 9},
                      Case{"openarena/oa_shouse.obj", {-0.31, -1, 0.22}, ReceiverKind::Everywhere, 9},
                      Case{"loinesg-city/city.obj", {0.505259, -0.379456, 0.775066}, ReceiverKind::Surfaces, 1}),
    [](const auto& info) { return "case" + std::to_string(info.index); });

// A farm's DAG-MH: each farm tile baked by a worker into parts, sent as bytes, merged at
// the coordinator in any order: the bytes of the bake in one process, for farm tiles
// larger and smaller than the bake's own.
TEST(DagMhFarmTiles, MergedInAnyOrderGiveTheLocalBytes) {
  const Scene scene = openScene("city:5");
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection({0.3, -1, 0.2}), 11);
  ReceiverDeclaration d;
  d.kind = ReceiverKind::Surfaces;
  BakeOptions options;
  const DagMh local = bakeDagMh(scene, grid, options, d);
  const BakeScene prepared(scene, grid, Renderer::Raster, 0, d);
  std::mt19937_64 rng(5);
  for (const int log2Farm : {10, 8}) {
    SCOPED_TRACE("farm tiles of 2^" + std::to_string(log2Farm));
    options.log2TileSize = log2Farm;
    const uint64_t n = grid.resolution() >> log2Farm;
    std::vector<uint64_t> order(n * n);
    for (uint64_t i = 0; i < order.size(); ++i) order[i] = i;
    std::shuffle(order.begin(), order.end(), rng);
    DagMhBuilder builder(grid.log2Resolution, dagMhPartLog2(grid.log2Resolution, log2Farm));
    for (const uint64_t i : order) {
      const std::vector<uint8_t> bytes = encodeDagMhTiles(bakeDagMhFarmTile(prepared, options, i % n, i / n));
      for (DagMhTile& part : decodeDagMhTiles(bytes.data(), bytes.size(), "farm tile")) builder.addTile(std::move(part));
    }
    const DagMh farm = builder.finish();
    EXPECT_EQ(farm.nodes, local.nodes);
    EXPECT_EQ(farm.treelets, local.treelets);
    EXPECT_EQ(farm.values.factors, local.values.factors);
    EXPECT_EQ(std::memcmp(farm.values.chunks.data(), local.values.chunks.data(), local.values.chunks.size() * 20), 0);
    EXPECT_EQ(farm.skip.size(), local.skip.size());
  }
  EXPECT_THROW(bakeDagMhFarmTile(prepared, options, 8, 0), InputError);
}

DmhArtifact smallArtifact() {
  const Scene scene = openScene("city:4");
  DmhArtifact a;
  a.grid = makeGrid(scene, LightFrame::fromDirection({0.3, -1, 0.2}), 10);
  a.options.receivers = ReceiverKind::Surfaces;
  ReceiverDeclaration d;
  d.kind = ReceiverKind::Surfaces;
  a.receiverHash = receiverHash(d);
  a.sceneHash = sceneHash(scene);
  a.dag = bakeDagMh(scene, a.grid, a.options, d);
  return a;
}

TEST(DmhFile, RoundTripsRawAndCompressed) {
  const DmhArtifact a = smallArtifact();
  ASSERT_GT(a.dag.skipLevel, 0);
  for (const bool zstd : {false, true}) {
    const std::vector<uint8_t> bytes = encodeDmh(a, zstd);
    EXPECT_TRUE(isDmh(bytes.data(), bytes.size()));
    const DmhArtifact b = decodeDmh(bytes.data(), bytes.size(), "x.dmh");
    EXPECT_EQ(b.dag.nodes, a.dag.nodes);
    EXPECT_EQ(b.dag.treelets, a.dag.treelets);
    EXPECT_EQ(b.dag.values.factors, a.dag.values.factors);
    EXPECT_EQ(b.dag.values.count, a.dag.values.count);
    EXPECT_EQ(std::memcmp(b.dag.values.chunks.data(), a.dag.values.chunks.data(), a.dag.values.chunks.size() * 20), 0);
    EXPECT_EQ(b.receiverHash, a.receiverHash);
    EXPECT_EQ(b.sceneHash, a.sceneHash);
    EXPECT_EQ(b.options, a.options);
    EXPECT_EQ(b.grid.resolution(), a.grid.resolution());
    EXPECT_EQ(encodeDmh(b, zstd), bytes);
  }
}

void reseal(std::vector<uint8_t>& b) {
  const uint64_t sum = XXH3_64bits(b.data(), b.size() - 8);
  std::memcpy(b.data() + b.size() - 8, &sum, 8);
}

TEST(DmhFile, DamageIsRefusedWithAReason) {
  const std::vector<uint8_t> good = encodeDmh(smallArtifact(), false);
  // Truncated anywhere, a flipped bit anywhere: refused (the checksum first).
  for (size_t n = 0; n < good.size(); n += 1 + good.size() / 300)
    EXPECT_THROW(decodeDmh(good.data(), n, "t.dmh"), FormatError) << n;
  std::mt19937_64 rng(3);
  for (int i = 0; i < 200; ++i) {
    std::vector<uint8_t> bad = good;
    bad[rng() % bad.size()] ^= uint8_t(1u << (rng() % 8));
    EXPECT_THROW(decodeDmh(bad.data(), bad.size(), "t.dmh"), FormatError);
  }
  // Behind a valid checksum, the readers' own checks: refused or, where a changed word is
  // one lookups may read (a treelet bit, a factor), accepted and in bounds.
  int refused = 0;
  for (int i = 0; i < 400; ++i) {
    std::vector<uint8_t> bad = good;
    bad[12 + rng() % (bad.size() - 20)] ^= uint8_t(1u << (rng() % 8));
    reseal(bad);
    try {
      const DmhArtifact a = decodeDmh(bad.data(), bad.size(), "t.dmh");
      const DagMhQuery q(a.grid, a.dag);
      for (int64_t y = 0; y < 1024; y += 5)
        for (int64_t x = 0; x < 1024; x += 5) (void)q.voxelShadowed({x, y, 500});
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("t.dmh"), std::string::npos) << e.what();
      ++refused;
    }
  }
  EXPECT_GT(refused, 40);
  // A .cpvs reader names what it was given.
  EXPECT_FALSE(isDmh(good.data(), 3));
}

}  // namespace
}  // namespace cpvs
