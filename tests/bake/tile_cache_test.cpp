// Edits re-bake only what they reach: a bake through the tile cache takes every tile whose
// key (the triangles reaching it, the grid, the options) it holds, and gives a full bake's
// bytes after no change (every tile taken), a moved building, a deleted one (which shifts
// every later triangle's index) and a new one; a changed sun takes nothing; a damaged or
// misplaced cache file is baked again; the folder stays within its bound; bakes the keys
// cannot vouch for (declared receivers, the Embree renderer) bake every tile.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "cpvs/bake/bake.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/tile_cache.h"
#include "cpvs/bake/tile_key.h"
#include "cpvs/bake/tile_plan.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/scene/boxes.h"
#include "dag_testing.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

namespace fs = std::filesystem;

struct Building {
  Vec3 lo, hi;
};

/// A 64 x 64 ground, a pole that holds the scene's height, and the buildings: every
/// variant has the same bounds, so the same grid.
Scene street(const std::vector<Building>& buildings) {
  Scene s;
  testing::appendQuad(s, {0, 0, 0}, {0, 0, 64}, {64, 0, 64}, {64, 0, 0});
  appendBox(s, {0, 0, 0}, {0.5, 24, 0.5});
  for (const Building& b : buildings) appendBox(s, b.lo, b.hi);
  finalizeScene(s);
  return s;
}

const std::vector<Building> kBuildings{{{6, 0, 6}, {12, 9, 14}},  {{20, 0, 8}, {26, 14, 13}}, {{40, 0, 5}, {47, 6, 12}},
                                       {{8, 0, 30}, {15, 11, 38}}, {{30, 0, 30}, {36, 7, 35}}, {{50, 0, 44}, {57, 16, 52}},
                                       {{12, 0, 50}, {18, 5, 57}}};

struct CachedBake {
  Dag dag;
  uint64_t reused = 0;
};

CachedBake bakeThrough(TileCache& cache, const Scene& scene, const Vec3& sun, const BakeOptions& options,
                       Renderer renderer = Renderer::Raster, const ReceiverDeclaration& receivers = {}) {
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection(sun), 9);
  const BakeScene prepared(scene, grid, renderer, 0, receivers);
  StageTimes st;
  CachedBake b;
  b.dag = bakeGrid(prepared, options, &st, nullptr, &cache);
  b.reused = st.tilesReused;
  return b;
}

Dag fullBake(const Scene& scene, const Vec3& sun, const BakeOptions& options) {
  return testing::bakeWith(scene, makeGrid(scene, LightFrame::fromDirection(sun), 9), options);
}

class TileCacheTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("cpvs_tile_cache_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    options_.log2TileSize = 6;  // 64 tiles
  }
  void TearDown() override { fs::remove_all(dir_); }
  uint64_t folderBytes() const {
    uint64_t total = 0;
    for (const auto& e : fs::directory_iterator(dir_)) total += e.file_size();
    return total;
  }
  fs::path dir_;
  BakeOptions options_;
  const Vec3 sun_{0.3, -1, 0.2};
  const uint64_t tiles_ = TilePlan(9, 6).count();
};

TEST_F(TileCacheTest, AnEditedSceneReusesTheTilesItDidNotReachAndGivesAFullBakesBytes) {
  TileCache cache(dir_.string(), uint64_t(1) << 30);
  const Scene base = street(kBuildings);
  const CachedBake first = bakeThrough(cache, base, sun_, options_);
  EXPECT_EQ(first.reused, 0u);
  testing::expectSameDag(first.dag, fullBake(base, sun_, options_));

  const CachedBake again = bakeThrough(cache, base, sun_, options_);
  EXPECT_EQ(again.reused, tiles_) << "nothing changed: every tile is taken";
  testing::expectSameDag(again.dag, first.dag);

  std::vector<Building> moved = kBuildings;
  moved[1].lo = moved[1].lo + Vec3{4, 0, 3}, moved[1].hi = moved[1].hi + Vec3{4, 0, 3};
  std::vector<Building> deleted = kBuildings;
  deleted.erase(deleted.begin() + 2);  // every later building's triangles move down the list
  std::vector<Building> added = kBuildings;
  added.push_back({{44, 0, 24}, {50, 10, 30}});
  for (const auto& [name, buildings] : {std::pair{"moved", moved}, std::pair{"deleted", deleted}, std::pair{"added", added}}) {
    SCOPED_TRACE(name);
    const Scene edited = street(buildings);
    const CachedBake b = bakeThrough(cache, edited, sun_, options_);
    EXPECT_GT(b.reused, tiles_ / 2) << "one building reaches a few tiles";
    EXPECT_LT(b.reused, tiles_) << "and those are baked again";
    testing::expectSameDag(b.dag, fullBake(edited, sun_, options_));
    EXPECT_EQ(b.dag.bytes(), fullBake(edited, sun_, options_).bytes());
  }
  // A grid smaller than the tile size: one tile, the grid's own size, kept too.
  BakeOptions wide = options_;
  wide.log2TileSize = 12;
  (void)bakeThrough(cache, base, sun_, wide);
  EXPECT_EQ(bakeThrough(cache, base, sun_, wide).reused, 1u);
  // Another sun: another grid, nothing to take.
  const Vec3 otherSun{-0.2, -1, 0.35};
  const CachedBake turned = bakeThrough(cache, base, otherSun, options_);
  EXPECT_EQ(turned.reused, 0u);
  testing::expectSameDag(turned.dag, fullBake(base, otherSun, options_));
  EXPECT_GT(cache.hits(), 0u);
}

TEST_F(TileCacheTest, DamagedOrMisplacedFilesAreBakedAgainAndTheFolderKeepsItsBound) {
  const Scene base = street(kBuildings);
  {
    TileCache cache(dir_.string(), uint64_t(1) << 30);
    (void)bakeThrough(cache, base, sun_, options_);
  }
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir_)) files.push_back(e.path());
  ASSERT_EQ(files.size(), tiles_);
  std::sort(files.begin(), files.end());
  // One file torn, one replaced by another tile's (a key that names the wrong tile).
  fs::resize_file(files[0], fs::file_size(files[0]) / 2);
  fs::copy_file(files[2], files[1], fs::copy_options::overwrite_existing);
  {
    TileCache cache(dir_.string(), uint64_t(1) << 30);
    const CachedBake b = bakeThrough(cache, base, sun_, options_);
    EXPECT_EQ(b.reused, tiles_ - 2);
    testing::expectSameDag(b.dag, fullBake(base, sun_, options_));
  }
  // Bounded: a quarter of what the tiles take; the least recently used go first.
  const uint64_t all = folderBytes();
  fs::remove_all(dir_);
  TileCache small(dir_.string(), all / 4);
  const CachedBake b = bakeThrough(small, base, sun_, options_);
  EXPECT_LE(folderBytes(), all / 4);
  EXPECT_GT(folderBytes(), 0u);
  testing::expectSameDag(b.dag, fullBake(base, sun_, options_));
}

TEST_F(TileCacheTest, BakesTheKeysCannotVouchForBakeEveryTile) {
  TileCache cache(dir_.string(), uint64_t(1) << 30);
  const Scene base = street(kBuildings);
  ReceiverDeclaration surfaces;
  surfaces.kind = ReceiverKind::Surfaces;
  BakeOptions declared = options_;
  declared.receivers = ReceiverKind::Surfaces;
  BakeOptions embree = options_;
  embree.renderer = Renderer::Embree;
  for (int run = 0; run < 2; ++run) {
    EXPECT_EQ(bakeThrough(cache, base, sun_, declared, Renderer::Raster, surfaces).reused, 0u);
    EXPECT_EQ(bakeThrough(cache, base, sun_, embree, Renderer::Embree).reused, 0u);
  }
  EXPECT_TRUE(fs::is_empty(dir_));
  const OrthoGrid grid = makeGrid(base, LightFrame::fromDirection(sun_), 9);
  EXPECT_FALSE(tileKey(BakeScene(base, grid, Renderer::Embree), embree, 0, 0));
  EXPECT_TRUE(tileKey(BakeScene(base, grid, Renderer::Raster), options_, 0, 0));
}

}  // namespace
}  // namespace cpvs
