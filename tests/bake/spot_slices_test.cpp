// A spot light's depth maps (NOTES §1.4 item 2): the exact rasterizer and the Embree
// renderer against a brute-force double-precision perspective caster, texel by texel,
// with geometry nearer than near (its column is shadowed from slice 0), geometry beyond
// far, closed buildings (exact and approximate exit), a lamp inside a level, and the
// cone's texels cast no ray. Then the rasterizer's own rules on a spot grid: fused masks,
// tiles against the whole grid, and tiles it skips.
#include <gtest/gtest.h>

#include <optional>

#include "cpvs/bake/column_masks.h"
#include "cpvs/bake/raster_scene.h"
#include "cpvs/bake/raster_slices.h"
#include "cpvs/bake/texel_slices.h"
#include "cpvs/light/perspective_grid.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/scene/source.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

using testing::LampCase;

class SpotSlices : public ::testing::TestWithParam<LampCase> {
 protected:
  // The case's scene and lamp; false when the scene is a shared one that is not here.
  bool open() {
    if (!testing::openLamp(GetParam(), scene_, center_, grid_)) return false;
    if (std::string(GetParam().name) == "city_flood") {
      // A small card just in front of the lamp, nearer than near: its texels are shadowed
      // from slice 0 on.
      const LightFrame& f = grid_->frame();
      const Vec3 at = grid_->position() + f.dir * (grid_->near() * 0.5);
      const double r = grid_->near() * 0.2;
      testing::appendQuad(scene_, at - f.u * r - f.v * r, at + f.u * r - f.v * r, at + f.u * r + f.v * r, at - f.u * r + f.v * r);
      finalizeScene(scene_);
    }
    return true;
  }
  Scene scene_;
  Vec3 center_;
  std::optional<PerspectiveGrid> grid_;
};

TEST_P(SpotSlices, RenderersEqualTheBruteForceOnEveryClearTexel) {
  const LampCase& c = GetParam();
  if (!open()) GTEST_SKIP() << "shared/scenes is not beside the project";
  const Scene& scene = scene_;
  const PerspectiveGrid& grid = *grid_;
  const uint32_t R = uint32_t(grid.resolution());
  const RayScene rays(scene, center_);
  const RasterScene raster(scene, grid, c.tanCone);
  for (ExitMode exit : {ExitMode::Exact, ExitMode::Approx}) {
    SCOPED_TRACE(std::string(c.name) + (exit == ExitMode::Exact ? " exact" : " approx"));
    TexelSlices got, rastered;
    renderTexelSlices(rays, grid, c.tanCone, ClosedMode::Auto, exit, 0, 0, R, R, got);
    rasterTexelSlices(raster, ClosedMode::Auto, exit, 0, 0, R, R, rastered);
    int rasterFailures = 0;
    uint64_t ambiguous = 0, compared = 0, nearShadowed = 0, hit = 0, beyond = 0, interiors = 0, coneMissed = 0;
    int failures = 0;
    for (uint32_t y = 0; y < R; ++y)
      for (uint32_t x = 0; x < R; ++x) {
        uint32_t wantLo = 0, wantHi = 0;
        bool amb = false;
        testing::bruteForceSpotTexel(scene, grid, c.tanCone, ClosedMode::Auto, exit, x, y, wantLo, wantHi, amb);
        const size_t at = size_t(y) * R + x;
        if (amb) {
          ++ambiguous;
          continue;
        }
        ++compared;
        const bool missed = grid.coneMissesTexel(x, y, c.tanCone);
        coneMissed += missed;
        nearShadowed += !missed && wantLo == 0;
        hit += !missed && wantLo < R;
        beyond += !missed && wantLo == R;
        interiors += wantHi > wantLo && !missed;
        if ((got.firstUndefined[at] != wantLo || got.firstShadowed[at] != wantHi) && failures++ < 10)
          ADD_FAILURE() << "texel (" << x << ", " << y << "): " << got.firstUndefined[at] << ".." << got.firstShadowed[at]
                        << ", the brute force " << wantLo << ".." << wantHi;
        if ((rastered.firstUndefined[at] != wantLo || rastered.firstShadowed[at] != wantHi) && rasterFailures++ < 10)
          ADD_FAILURE() << "rasterized texel (" << x << ", " << y << "): " << rastered.firstUndefined[at] << ".."
                        << rastered.firstShadowed[at] << ", the brute force " << wantLo << ".." << wantHi;
      }
    EXPECT_EQ(failures, 0);
    EXPECT_EQ(rasterFailures, 0);
    EXPECT_LT(ambiguous, compared / 20) << "too many ambiguous texels for the comparison to mean much";
    EXPECT_GT(hit, compared / 10) << "the lamp must light geometry";
    if (c.tanCone < c.tanHalfFov * 1.414) {
      EXPECT_GT(coneMissed, 0u);
    }
    if (std::string(c.name) == "city_flood") {
      EXPECT_GT(nearShadowed, 0u) << "the card before near shadows its columns from slice 0";
      EXPECT_GT(beyond, 0u) << "and the flood light sees past the city";
      if (exit == ExitMode::Exact) {
        EXPECT_GT(interiors, 0u) << "the buildings are closed";
      }
    }
  }
}

TEST_P(SpotSlices, RasterizedMasksTilesAndSkippedTilesAgree) {
  const LampCase& c = GetParam();
  if (!open()) GTEST_SKIP() << "shared/scenes is not beside the project";
  const uint32_t R = uint32_t(grid_->resolution());
  // The case's cone, and one half as wide whose corner tiles lie outside it.
  for (double tanCone : {c.tanCone, c.tanHalfFov * 0.5}) {
    SCOPED_TRACE("cone " + std::to_string(tanCone));
    const RasterScene raster(scene_, *grid_, tanCone);
    TexelSlices whole;
    rasterTexelSlices(raster, ClosedMode::Auto, ExitMode::Exact, 0, 0, R, R, whole);
    const uint32_t T = 32;
    uint64_t skipped = 0;
    for (uint32_t ty = 0; ty < R; ty += T)
      for (uint32_t tx = 0; tx < R; tx += T) {
        SCOPED_TRACE("tile at " + std::to_string(tx) + ", " + std::to_string(ty));
        TexelSlices tile;
        rasterTexelSlices(raster, ClosedMode::Auto, ExitMode::Exact, tx, ty, T, T, tile);
        for (uint32_t y = 0; y < T; ++y)
          for (uint32_t x = 0; x < T; ++x) {
            const size_t at = size_t(ty + y) * R + tx + x, in = size_t(y) * T + x;
            ASSERT_EQ(tile.firstUndefined[in], whole.firstUndefined[at]) << x << ", " << y;
            ASSERT_EQ(tile.firstShadowed[in], whole.firstShadowed[at]) << x << ", " << y;
          }
        // The fused path resolves the same masks.
        ColumnMasks fused, plain;
        rasterColumnMasks(raster, ClosedMode::Auto, ExitMode::Exact, UndefinedRule::New, tx, ty, T, T, fused);
        buildColumnMasks(tile, T, T, R, UndefinedRule::New, plain);
        ASSERT_EQ(fused.begin, plain.begin);
        ASSERT_EQ(fused.slice, plain.slice);
        ASSERT_EQ(fused.mask, plain.mask);
        // A tile the scene does not touch (nothing there, or outside the cone) resolves
        // to all lit, what the bake writes for it without rendering.
        if (!raster.touchesRectangle(tx, ty, T, T)) {
          ++skipped;
          EXPECT_TRUE(plain.slice.empty()) << "a skipped tile must resolve to all lit";
        }
      }
    if (tanCone == c.tanHalfFov * 0.5) {
      EXPECT_GE(skipped, 4u) << "the corner tiles are outside the cone";
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Lamps, SpotSlices,
    ::testing::Values(
        // A flood light over the procedural city, wide and looking down at an angle.
        LampCase{"city_flood", "city:3", false, {0.1, 0.45, -0.05}, {0.25, -1, 0.15}, 1.4, 1.2, 0.02, 1.5, 7},
        // A narrow spot across the city, low: the far plane cuts into the buildings.
        LampCase{"city_street", "city:3:7", false, {-0.3, -0.3, 0.2}, {1, -0.15, -0.3}, 0.5, 0.45, 0.005, 0.6, 7},
        // A lamp inside a Quake 3 level, looking along a corridor and down.
        LampCase{"quake_house", "openarena/oa_shouse.obj", true, {0.05, 0.1, 0}, {0.3, -0.4, 1}, 1.0, 1.0, 0.002, 1.2, 7}),
    [](const ::testing::TestParamInfo<LampCase>& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace cpvs
