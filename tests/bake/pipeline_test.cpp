// The whole bake on real and generated scenes, against brute-force references: texel
// depths against every-ray-against-every-triangle, every voxel of the baked DAG against
// the dense voxel classification, tilings and construction variants against each other,
// and lookups against exact Embree shadow rays.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <random>

#include "cpvs/bake/tile_plan.h"
#include "cpvs/bake/bake.h"
#include "cpvs/base/error.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/dag/assemble_roots.h"
#include "cpvs/dag/merge.h"
#include "cpvs/dag/streaming_merger.h"
#include "cpvs/eval/verify.h"
#include "dag_testing.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

using testing::bakeTileWith;
using testing::bakeWith;

using testing::bruteForceDepths;
using testing::expectOptimal;
using testing::expectSameDag;

struct SceneCase {
  std::string name;      // for messages
  std::string relative;  // under shared/scenes, or "" for the procedural city
  Vec3 sun;
};

Scene openCase(const SceneCase& c) {
  return c.relative.empty() ? openScene("city:4:7") : openScene(testing::sharedScenesDir() + "/" + c.relative);
}

class ScenePipeline : public ::testing::TestWithParam<SceneCase> {
 protected:
  void SetUp() override {
    if (!GetParam().relative.empty() && testing::sharedScenesDir().empty())
      GTEST_SKIP() << "shared/scenes is not beside the project: skipping " << GetParam().relative;
    scene_ = openCase(GetParam());
  }
  Scene scene_;
};

// The packet renderer's texel depths equal a double-precision brute force for every
// texel whose ray does not graze an edge or a slice boundary; those may differ by float
// rounding and are few.
TEST_P(ScenePipeline, DepthMapsMatchBruteForce) {
  for (ExitMode exit : {ExitMode::Exact, ExitMode::Approx}) {
    OrthoGrid grid = makeGrid(scene_, LightFrame::fromDirection(GetParam().sun), 6);
    RayScene rays(scene_, grid.origin);
    const uint64_t R = grid.resolution();
    TexelSlices got, want;
    std::vector<uint8_t> ambiguous;
    renderTexelSlices(rays, grid, ClosedMode::Auto, exit, 0, 0, uint32_t(R), uint32_t(R), got);
    bruteForceDepths(scene_, grid, ClosedMode::Auto, exit, want, ambiguous);
    uint64_t bad = 0, skipped = 0, hitTexels = 0, interiorTexels = 0;
    for (uint64_t i = 0; i < R * R; ++i) {
      hitTexels += want.firstUndefined[i] < R;
      interiorTexels += want.firstShadowed[i] > want.firstUndefined[i];
      if (ambiguous[i]) {
        ++skipped;
        continue;
      }
      if (got.firstUndefined[i] != want.firstUndefined[i] || got.firstShadowed[i] != want.firstShadowed[i]) {
        if (++bad <= 5)
          ADD_FAILURE() << "texel " << i % R << "," << i / R << ": renderer lo/hi " << got.firstUndefined[i] << "/" << got.firstShadowed[i]
                        << ", brute force " << want.firstUndefined[i] << "/" << want.firstShadowed[i];
      }
    }
    EXPECT_EQ(bad, 0u);
    EXPECT_LT(skipped, R * R / 50) << "too many ambiguous texels for the comparison to mean much";
    EXPECT_GT(hitTexels, R * R / 10) << "the scene should cover the grid";
    const auto closedTriangles = std::count(scene_.closed.begin(), scene_.closed.end(), 1);
    if (2 * size_t(closedTriangles) > scene_.triangleCount()) {
      EXPECT_GT(interiorTexels, 0u) << "a mostly closed scene has interiors";
    }
  }
}

// Every defined voxel of a full bake equals the dense brute-force classification, and
// undefined voxels lie inside closed geometry.
TEST_P(ScenePipeline, EveryDefinedVoxelMatchesDenseReference) {
  // The brute force is every ray against every triangle: larger scenes stay at 64.
  for (int log2R : {6, 7}) {
    if (log2R > 6 && scene_.triangleCount() > 10000) break;
    OrthoGrid grid = makeGrid(scene_, LightFrame::fromDirection(GetParam().sun), log2R);
    RayScene rays(scene_, grid.origin);
    BakeOptions opt;
    opt.log2TileSize = 5;  // several tiles even at small R
    Dag dag = bakeWith(scene_, grid, opt);
    expectOptimal(dag);
    const uint64_t R = grid.resolution();
    TexelSlices want;
    std::vector<uint8_t> ambiguous;
    bruteForceDepths(scene_, grid, ClosedMode::Auto, ExitMode::Exact, want, ambiguous);
    uint64_t bad = 0, undefinedVoxels = 0, undefinedChecked = 0, undefinedOutside = 0;
    for (uint64_t y = 0; y < R; ++y)
      for (uint64_t x = 0; x < R; ++x) {
        size_t at = y * R + x;
        if (ambiguous[at]) continue;
        for (uint64_t z = 0; z < R; ++z) {
          bool shadowed = dagVoxelShadowed(dag, x, y, z);
          if (z < want.firstUndefined[at]) {
            bad += shadowed;
          } else if (z >= want.firstShadowed[at]) {
            bad += !shadowed;
          } else {
            ++undefinedVoxels;
          }
        }
        // A voxel strictly between the enter and exit slices lies inside: its centre
        // must be inside a closed part by face counting.
        if (want.firstShadowed[at] >= want.firstUndefined[at] + 3) {
          Vec3 centre = grid.worldFromVoxel(Vec3{x + 0.5, y + 0.5, (want.firstUndefined[at] + want.firstShadowed[at]) / 2 + 0.5});
          ++undefinedChecked;
          undefinedOutside += rays.closedNesting(centre, -grid.frame.dir, 1e9, ClosedMode::Auto) <= 0;
        }
      }
    EXPECT_EQ(bad, 0u) << "R=" << R;
    EXPECT_EQ(undefinedOutside, 0u) << "of " << undefinedChecked << " undefined columns checked, R=" << R;
  }
}

// A grid with fewer depth slices (--depth-slices) is coarser in depth only: the scene's
// depth range lies in its first D slices, every defined voxel still equals the dense
// brute force of that grid, and every slice behind the scene repeats the last one (what a
// lookup behind the grid reads), at 8 and 32 slices of 64; a D that is not a power of two is refused.
TEST_P(ScenePipeline, FewerDepthSlicesHoldTheSceneInTheFirstOnes) {
  const int log2R = 6;
  const uint64_t R = uint64_t(1) << log2R;
  const LightFrame frame = LightFrame::fromDirection(GetParam().sun);
  const OrthoGrid cubic = makeGrid(scene_, frame, log2R);
  for (uint64_t D : {uint64_t(8), uint64_t(32)}) {
    const OrthoGrid grid = makeGrid(scene_, frame, log2R, D);
    EXPECT_EQ(grid.extent, cubic.extent);
    EXPECT_EQ(grid.d0, cubic.d0);
    EXPECT_NEAR(grid.sliceSize(), cubic.sliceSize() * double(R) / double(D), 1e-12 * cubic.depthExtent);
    BakeOptions opt;
    opt.log2TileSize = 5;
    Dag dag = bakeWith(scene_, grid, opt);
    expectOptimal(dag);
    TexelSlices want;
    std::vector<uint8_t> ambiguous;
    bruteForceDepths(scene_, grid, ClosedMode::Auto, ExitMode::Exact, want, ambiguous);
    uint64_t bad = 0, hits = 0, behindDiffers = 0;
    for (uint64_t y = 0; y < R; ++y)
      for (uint64_t x = 0; x < R; ++x) {
        const size_t at = y * R + x;
        if (want.firstUndefined[at] < R) {
          ++hits;
          EXPECT_LT(want.firstUndefined[at], D) << "a hit behind the scene's slices at " << x << "," << y;
        }
        const bool last = dagVoxelShadowed(dag, x, y, D - 1);
        for (uint64_t z = D; z < R; ++z) behindDiffers += dagVoxelShadowed(dag, x, y, z) != last;
        if (ambiguous[at]) continue;
        for (uint64_t z = 0; z < R; ++z) {
          const bool shadowed = dagVoxelShadowed(dag, x, y, z);
          if (z < want.firstUndefined[at]) bad += shadowed;
          else if (z >= want.firstShadowed[at]) bad += !shadowed;
        }
      }
    EXPECT_GT(hits, R * R / 10) << "D=" << D;
    EXPECT_EQ(bad, 0u) << "D=" << D;
    EXPECT_EQ(behindDiffers, 0u) << "D=" << D;
  }
  EXPECT_THROW(makeGrid(scene_, frame, log2R, R + 1), InputError);
  EXPECT_THROW(makeGrid(scene_, frame, log2R, 24), InputError);  // not a power of two
  EXPECT_EQ(makeGrid(scene_, frame, log2R, 16).depthSlices, 16u);
  EXPECT_EQ(makeGrid(scene_, frame, log2R, 16).depthShift(), 2);
  EXPECT_EQ(makeGrid(scene_, frame, log2R, R).depthSlices, 0u);
  EXPECT_EQ(makeGrid(scene_, frame, log2R, R).depthExtent, cubic.depthExtent);
}

// Tile sizes 64, 256 and whole-grid give the same DAG: a voxel's resolved value depends
// only on its 8x8 texel column, which no tile border splits, and homogeneity above the
// tiles is decided from the merged children exactly as in an untiled build. So not only
// every defined voxel but every byte agrees.
TEST_P(ScenePipeline, TileSizesAgreeToTheByte) {
  OrthoGrid grid = makeGrid(scene_, LightFrame::fromDirection(GetParam().sun), 9);
  BakeOptions opt;
  opt.log2TileSize = 9;
  Dag whole = bakeWith(scene_, grid, opt);
  for (int log2T : {6, 8}) {
    opt.log2TileSize = log2T;
    Dag tiled = bakeWith(scene_, grid, opt);
    expectSameDag(whole, tiled);
    EXPECT_EQ(whole.bytes(), tiled.bytes()) << "tile " << (1 << log2T);
  }
}

// Sub-DAGs merged in a shuffled order give the same bytes as the in-order merge.
TEST_P(ScenePipeline, MergeOrderDoesNotChangeBytes) {
  OrthoGrid grid = makeGrid(scene_, LightFrame::fromDirection(GetParam().sun), 8);
  BakeOptions opt;
  opt.log2TileSize = 6;
  const uint64_t n = TilePlan(grid.log2Resolution, opt.log2TileSize).perSide();
  std::vector<Dag> tiles;
  for (uint64_t i = 0; i < n * n; ++i) tiles.push_back(bakeTileWith(scene_, grid, i % n, i / n, opt));
  Dag inOrder = bakeWith(scene_, grid, opt);
  std::vector<uint64_t> order(n * n);
  for (uint64_t i = 0; i < n * n; ++i) order[i] = i;
  std::mt19937 rng(3);
  for (int round = 0; round < 3; ++round) {
    std::shuffle(order.begin(), order.end(), rng);
    StreamingMerger merger(opt.compress);
    for (uint64_t k : order) merger.add(Dag(tiles[k]));
    Dag shuffled = assembleRoots(*merger.finish(), opt.hash, opt.compress);
    expectSameDag(inOrder, shuffled);
    expectOptimal(shuffled);
    CpvsArtifact a, b;
    a.grid = b.grid = grid;
    a.options = b.options = opt;
    a.sceneHash = b.sceneHash = sceneHash(scene_);
    a.dag = inOrder;
    b.dag = shuffled;
    EXPECT_EQ(encodeCpvs(a, false), encodeCpvs(b, false));
  }
}

// Culled and unculled insertion, top-down and bottom-up compression, and a weak 8-valued
// hash that collides all the time, compute the same optimal DAG of the same voxels.
TEST_P(ScenePipeline, ConstructionVariantsAgreeToTheByte) {
  OrthoGrid grid = makeGrid(scene_, LightFrame::fromDirection(GetParam().sun), 8);
  RayScene rays(scene_, grid.origin);
  BakeOptions base;
  base.log2TileSize = 7;
  Dag reference = bakeWith(scene_, grid, base);
  expectOptimal(reference);
  std::mt19937_64 rng(11);
  const uint64_t R = grid.resolution();
  for (bool cull : {true, false})
    for (CompressMode mode : {CompressMode::TopDown, CompressMode::BottomUp})
      for (HashKind hash : {HashKind::Xxh3, HashKind::WeakForTests}) {
        BakeOptions opt = base;
        opt.cull = cull;
        opt.compress = mode;
        opt.hash = hash;
        SCOPED_TRACE(::testing::Message() << "cull " << cull << " mode " << int(mode) << " hash " << int(hash));
        Dag dag = bakeWith(scene_, grid, opt);
        if (hash == base.hash) {
          expectSameDag(reference, dag);
          continue;
        }
        // Levels are ordered by hash, so another hash orders them differently: the
        // same optimal DAG then shows as the same node count per level and the same
        // voxels (sampled), with no duplicate node despite the collisions.
        expectOptimal(dag);
        ASSERT_EQ(dag.levels.size(), reference.levels.size());
        EXPECT_EQ(dag.leaves.size(), reference.leaves.size());
        for (size_t l = 0; l < dag.levels.size(); ++l) EXPECT_EQ(dag.levels[l].size(), reference.levels[l].size());
        uint64_t differ = 0;
        for (int i = 0; i < 200000; ++i) {
          uint64_t x = rng() % R, y = rng() % R, z = rng() % R;
          differ += dagVoxelShadowed(dag, x, y, z) != dagVoxelShadowed(reference, x, y, z);
        }
        EXPECT_EQ(differ, 0u);
      }
}

// Binary lookups agree with exact shadow rays everywhere but within one voxel of a
// shadow boundary, and disagree there only rarely.
// Both exact oracles (Embree's rays and the TOP tree's shadow volumes) give the same
// answers away from boundaries too.
TEST_P(ScenePipeline, LookupsAgreeWithShadowRaysAwayFromBoundaries) {
  const TopTree psv = verificationTree(scene_, PsvLight::sun(LightFrame::fromDirection(GetParam().sun).dir));
  for (int log2R : {8, 10}) {
    CpvsArtifact art;
    art.grid = makeGrid(scene_, LightFrame::fromDirection(GetParam().sun), log2R);
    RayScene rays(scene_, art.grid.origin);
    art.dag = bakeWith(scene_, art.grid, art.options);
    art.sceneHash = sceneHash(scene_);
    ShadowQuery query(art.grid, PackedDag(art.dag));
    VerifyResult r = verifyArtifact(query, art.options.closed, scene_, rays, 20000, 5, {&psv});
    EXPECT_GT(r.samples, 15000u);
    EXPECT_EQ(r.mismatchElsewhere, 0u) << "R=" << art.grid.resolution();
    EXPECT_EQ(r.oraclesCompared, r.samples);
    EXPECT_EQ(r.oraclesDisagreeElsewhere, 0u) << "R=" << art.grid.resolution();
    EXPECT_LT(r.fractionNearBoundary(), 0.02) << "R=" << art.grid.resolution();
  }
}

// A filtered lookup (one walk per 8x8 leaf slice it touches) counts exactly the lit
// voxels of its footprint, voxel by voxel, including footprints that hang over the
// grid's sides, its near end (lit) and its far end (the last slice).
TEST_P(ScenePipeline, FilteredLookupsCountTheirFootprintVoxelByVoxel) {
  CpvsArtifact art;
  art.grid = makeGrid(scene_, LightFrame::fromDirection(GetParam().sun), 7);
  art.dag = bakeWith(scene_, art.grid, art.options);
  ShadowQuery query(art.grid, PackedDag(art.dag));
  const int64_t R = int64_t(art.grid.resolution());
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> coord(-0.1 * double(R), 1.1 * double(R));
  std::normal_distribution<double> normal;
  uint64_t differ = 0, partial = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vec3 p = art.grid.worldFromVoxel({coord(rng), coord(rng), coord(rng)});
    const Vec3 n = i % 4 == 0 ? Vec3{} : Vec3{normal(rng), normal(rng), normal(rng)};
    for (int pcf : {1, 3, 5, 9}) {
      const VoxelCoord v = query.voxelOf(p, n, pcf);
      int lit = 0;
      for (int dy = -pcf / 2; dy <= pcf / 2; ++dy)
        for (int dx = -pcf / 2; dx <= pcf / 2; ++dx) lit += !query.voxelShadowed({v.x + dx, v.y + dy, v.z});
      const float want = float(lit) / float(pcf * pcf);
      differ += query.filtered(p, n, pcf) != want;
      partial += want > 0 && want < 1;
    }
  }
  EXPECT_EQ(differ, 0u);
  EXPECT_GT(partial, 0u) << "no footprint straddled a shadow boundary: the test saw nothing";
}

// The same bake twice gives the same file bytes (threads do not leak into results): on
// every core, tiles pipelined, and on one thread, tile after tile.
TEST_P(ScenePipeline, BakesAreDeterministic) {
  CpvsArtifact a, b;
  a.grid = b.grid = makeGrid(scene_, LightFrame::fromDirection(GetParam().sun), 8);
  a.options.log2TileSize = b.options.log2TileSize = 6;
  a.dag = bakeWith(scene_, a.grid, a.options);
  {
    tbb::global_control oneThread(tbb::global_control::max_allowed_parallelism, 1);
    b.dag = bakeWith(scene_, b.grid, b.options);
  }
  a.sceneHash = b.sceneHash = sceneHash(scene_);
  EXPECT_EQ(encodeCpvs(a, true), encodeCpvs(b, true));
  // Embree's renderer keeps its texel slices per thread: two tiles in flight must not
  // share them.
  BakeOptions embree = a.options;
  embree.renderer = Renderer::Embree;
  const Dag pipelined = bakeWith(scene_, a.grid, embree);
  tbb::global_control oneThread(tbb::global_control::max_allowed_parallelism, 1);
  expectSameDag(pipelined, bakeWith(scene_, a.grid, embree));
}

INSTANTIATE_TEST_SUITE_P(
    Scenes, ScenePipeline,
    ::testing::Values(SceneCase{"city", "", {0.35, -1, 0.25}},
                      SceneCase{"city_straight_down", "", {0, -1, 0}},
                      SceneCase{"bunny", "stanford-bunny/bunny.obj", {0.3, -0.8, -0.5}},
                      SceneCase{"duck", "assimp-testmodels/duck.dae", {-1, -0.4, 0.2}},
                      SceneCase{"teapots_open", "assimp-testmodels/teapots.DAE", {0.2, -1, 0.6}},
                      SceneCase{"spider_mixed", "assimp-testmodels/spider.obj", {0.5, -1, 0.1}},
                      SceneCase{"shouse_open", "openarena/oa_shouse.obj", {0.4, -1, 0.3}}),
    [](const ::testing::TestParamInfo<SceneCase>& info) { return info.param.name; });

}  // namespace
}  // namespace cpvs
