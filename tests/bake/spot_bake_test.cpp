// A spot light's bake end to end (NOTES §1.4 items 3, 4 and 9): for surface points in its
// cone, the binary lookup of the baked DAG equals an exact segment ray to the light except
// within one perspective voxel of a boundary (the cone's edge is one), with no mismatch
// elsewhere, for both renderers, on a lamp over the procedural city and lamps in two real
// scenes; and the bytes do not depend on the tile size.
#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <random>

#include "cpvs/bake/bake.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/dag/packed_dag.h"
#include "cpvs/eval/verify.h"
#include "cpvs/query/shadow_query.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/scene/source.h"
#include "dag_testing.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

using testing::LampCase;

class SpotBake : public ::testing::TestWithParam<LampCase> {
 protected:
  void SetUp() override {
    if (!testing::openLamp(GetParam(), scene_, centre_, grid_)) GTEST_SKIP() << "shared/scenes is not beside the project";
  }

  Dag bake(const BakeOptions& options) const {
    const BakeScene prepared(scene_, *grid_, GetParam().tanCone, options.renderer);
    return bakeGrid(prepared, options);
  }

  Scene scene_;
  Vec3 centre_;
  std::optional<PerspectiveGrid> grid_;
};

TEST_P(SpotBake, LookupsEqualExactRaysAwayFromBoundaries) {
  const LampCase& c = GetParam();
  const RayScene rays(scene_, centre_);
  const TopTree psv = verificationTree(scene_, PsvLight::point(grid_->position()));
  for (Renderer renderer : {Renderer::Raster, Renderer::Embree}) {
    SCOPED_TRACE(optionName(renderer));
    BakeOptions options;
    options.renderer = renderer;
    options.log2TileSize = c.log2R - 1;  // four tiles
    const ShadowQuery query(*grid_, c.tanCone, PackedDag(bake(options)));
    const VerifyResult r = verifySpotArtifact(query, ClosedMode::Auto, scene_, rays, 6000, 11, nullptr, {&psv});
    EXPECT_EQ(r.oraclesCompared, r.samples);
    EXPECT_EQ(r.oraclesDisagreeElsewhere, 0u) << "Embree and the TOP tree differ away from a boundary";
    EXPECT_GT(r.samples, 4000u) << "the cone must hold enough of the scene's surfaces";
    EXPECT_GT(r.exactlyLit, r.samples / 10) << "the lamp must light some of them";
    EXPECT_LT(r.exactlyLit, r.samples * 9 / 10) << "and leave some in shadow";
    EXPECT_EQ(r.mismatchElsewhere, 0u);
    for (const SurfaceSample& s : r.elsewhereExamples)
      ADD_FAILURE() << "mismatch away from a boundary at (" << s.point.x << ", " << s.point.y << ", " << s.point.z
                    << ") normal (" << s.normal.x << ", " << s.normal.y << ", " << s.normal.z << ")";
    EXPECT_LT(r.fractionNearBoundary(), 0.05) << r.mismatchNearBoundary << " of " << r.samples;
    EXPECT_GT(r.nearBoundary, 0u) << "the cone's edge and the shadows are boundaries";
  }
}

TEST_P(SpotBake, TheSameBytesForAnyTileSize) {
  const LampCase& c = GetParam();
  BakeOptions options;
  options.log2TileSize = c.log2R;
  const Dag whole = bake(options);
  options.log2TileSize = 4;
  const Dag tiled = bake(options);
  testing::expectSameDag(whole, tiled);
  EXPECT_EQ(whole.bytes(), tiled.bytes());
}

// The spot query's filtered lookups against their definition, texel by texel through
// voxelShadowed, at random points of the frustum and beyond it: no light outside the cone,
// the frustum or behind the light, and the same count a footprint at a time.
TEST_P(SpotBake, FilteredLookupsCountTheirFootprintsTexels) {
  const LampCase& c = GetParam();
  BakeOptions options;
  const ShadowQuery query(*grid_, c.tanCone, PackedDag(bake(options)));
  const PerspectiveGrid& g = *grid_;
  std::mt19937_64 rng(5);
  const double R = double(g.resolution());
  std::uniform_real_distribution<double> voxel(-0.2 * R, 1.2 * R), unit(-1, 1);
  uint64_t outside = 0, partial = 0;
  for (int i = 0; i < 4000; ++i) {
    const Vec3 p = g.worldFromVoxel({voxel(rng), voxel(rng), std::abs(voxel(rng))});
    const Vec3 n{unit(rng), unit(rng), unit(rng)};
    for (int pcf : {1, 5, 9}) {
      const VoxelCoord v = query.voxelOf(p, n, pcf);
      uint32_t lit = 0;
      for (int64_t dy = -pcf / 2; dy <= pcf / 2; ++dy)
        for (int64_t dx = -pcf / 2; dx <= pcf / 2; ++dx) lit += !query.voxelShadowed({v.x + dx, v.y + dy, v.z});
      ASSERT_EQ(query.litTexels(p, n, pcf), lit) << "point " << i << " pcf " << pcf;
      if (pcf == 9 && lit > 0 && lit < 81) ++partial;
    }
    if (!g.insideCone(p, c.tanCone * 1.05) && query.voxelOf(p, n, 1).z >= 0) {
      ++outside;
      EXPECT_EQ(query.visibility(p, n), 0.0f) << "no light outside the cone";
    }
  }
  EXPECT_GT(outside, 100u);
  EXPECT_GT(partial, 10u);
  // Beyond far (the light's range) and behind the light.
  const Vec3 beyond = g.position() + g.frame().dir * (g.far() * 1.01);
  EXPECT_EQ(query.litTexels(beyond, {}, 9), 0u);
  EXPECT_TRUE(query.voxelShadowed(query.voxelOf(beyond, {}, 1)));
  const Vec3 behind = g.position() - g.frame().dir * g.near();
  EXPECT_EQ(query.visibility(behind, {}), 0.0f);
  EXPECT_EQ(query.litTexels(behind, g.frame().dir, 9), 0u);
}

INSTANTIATE_TEST_SUITE_P(
    Lamps, SpotBake,
    ::testing::Values(
        // A flood light over the procedural city, wide and looking down at an angle.
        LampCase{"city_flood", "city:3", false, {0.1, 0.45, -0.05}, {0.25, -1, 0.15}, 1.4, 1.2, 0.02, 1.5, 8},
        // A lamp inside a Quake 3 level, looking along a corridor and down.
        LampCase{"quake_house", "openarena/oa_shouse.obj", true, {0, 0, 0.05}, {0.3, -0.6, 1}, 1.0, 0.9, 0.002, 1.2, 8},
        // A street light over a real city block, looking down.
        LampCase{"city_block", "loinesg-city/city.obj", true, {0.02, 0.1, 0.03}, {0.1, -1, 0.05}, 1.2, 1.0, 0.002, 0.5, 8}),
    [](const ::testing::TestParamInfo<LampCase>& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace cpvs
