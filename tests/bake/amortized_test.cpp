// The amortized bake against the one-shot bake: any sequence of budgets (0, a microsecond,
// random, unlimited) gives the same DAG, byte for byte, with both renderers, every
// compression mode, culling on and off, tiles no triangle touches, and a real scene.
#include <gtest/gtest.h>

#include <random>

#include "cpvs/bake/amortized_bake.h"
#include "cpvs/bake/bake.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/scene/source.h"
#include "dag_testing.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

using namespace std::chrono_literals;

Dag amortized(const BakeScene& scene, const BakeOptions& options, uint64_t seed, AmortizedBake::Stats* stats = nullptr) {
  AmortizedBake bake(scene, options);
  std::mt19937_64 rng(seed);
  const std::chrono::nanoseconds budgets[] = {0ns, 1ns, 1us, 50us, 1ms, 20ms};
  uint64_t steps = 1;  // the step that returns done counts too
  while (!bake.step(seed == 0 ? 0ns : budgets[rng() % 6])) ++steps;
  EXPECT_EQ(bake.stats().steps, steps);
  // A step runs one unit, and more only while its budget lasts: with no budget, one each.
  if (seed == 0) {
    EXPECT_EQ(bake.stats().units, steps);
  }
  EXPECT_LE(steps, bake.stats().units);
  if (stats) *stats = bake.stats();
  return bake.takeResult();
}

void expectSameBytes(const Dag& a, const Dag& b, const OrthoGrid& grid) {
  CpvsArtifact x, y;
  x.grid = y.grid = grid;
  x.dag = a;
  y.dag = b;
  EXPECT_EQ(encodeCpvs(x, false), encodeCpvs(y, false));
}

TEST(AmortizedBake, AnyBudgetsGiveTheOneShotBytes) {
  const Scene scene = openScene("city:3:2");
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection({0.3, -1, 0.25}), 9);
  for (Renderer renderer : {Renderer::Raster, Renderer::Embree}) {
    const BakeScene prepared(scene, grid, renderer);
    for (CompressMode compress : {CompressMode::TopDown, CompressMode::BottomUp, CompressMode::None})
      for (bool cull : {true, false}) {
        BakeOptions o;
        o.renderer = renderer;
        o.compress = compress;
        o.cull = cull;
        o.log2TileSize = 7;  // 16 tiles, some touched by nothing
        const Dag oneShot = bakeGrid(prepared, o);
        for (uint64_t seed : {0u, 1u, 2u}) {
          AmortizedBake::Stats stats;
          const Dag stepped = amortized(prepared, o, seed, &stats);
          SCOPED_TRACE(std::string(optionName(renderer)) + " " + optionName(compress) + (cull ? " cull" : "") +
                       " seed " + std::to_string(seed));
          testing::expectSameDag(oneShot, stepped);
          expectSameBytes(oneShot, stepped, grid);
          EXPECT_GE(stats.units, 16u * 4);  // at least masks, pyramid, insert, merge per tile
        }
      }
  }
}

// Budgets of zero run one unit per step: a 128-row tile is rendered in stripes of 8 rows.
TEST(AmortizedBake, ZeroBudgetsRunOneUnitPerStep) {
  const Scene scene = openScene("city:2:1");
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection({0.2, -1, 0.1}), 7);
  const BakeScene prepared(scene, grid, Renderer::Raster);
  BakeOptions o;
  AmortizedBake bake(prepared, o);
  uint64_t steps = 1;
  while (!bake.step(0ns)) ++steps;
  EXPECT_EQ(bake.stats().steps, steps);
  EXPECT_EQ(bake.stats().units, steps);
  EXPECT_GE(steps, 128u / 8 + 5);  // 16 stripes, then pyramid, insert, compress, merge, final
  EXPECT_EQ(bake.tilesDone(), bake.tileCount());
  // Every unit counted once under its kind, each of which outlasts a budget of zero.
  std::vector<std::string> kinds;
  uint64_t units = 0;
  for (const auto& k : bake.stats().unitKinds) {
    kinds.push_back(k.name);
    units += k.count;
    EXPECT_EQ(k.overBudget, k.count) << k.name;
    EXPECT_GE(k.totalSeconds, k.longestSeconds);
    EXPECT_LE(k.longestSeconds, bake.stats().longestUnitSeconds);
  }
  EXPECT_EQ(units, steps);
  EXPECT_EQ(kinds, (std::vector<std::string>{"render and masks", "pyramid", "insert", "compress", "merge", "final merge and roots"}));
  EXPECT_TRUE(bake.step(0ns));  // done stays done
  testing::expectSameDag(bakeGrid(prepared, o), bake.takeResult());
  EXPECT_THROW(bake.takeResult(), std::logic_error);
}

TEST(AmortizedBake, RealSceneGivesTheOneShotBytes) {
  CPVS_SHARED_SCENE_OR_SKIP(path, "stanford-bunny/bunny.obj");
  const Scene scene = openScene(path);
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection({0.3, -0.8, -0.5}), 10);
  const BakeScene prepared(scene, grid, Renderer::Raster);
  BakeOptions o;
  o.log2TileSize = 8;
  const Dag oneShot = bakeGrid(prepared, o);
  expectSameBytes(oneShot, amortized(prepared, o, 7), grid);
}

}  // namespace
}  // namespace cpvs
