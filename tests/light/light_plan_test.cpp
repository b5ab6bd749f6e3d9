// Local lights as artists give them and the grids the planner makes of them (seed 000 §5,
// NOTES §1.4 item 10): refused input names the light and what is wrong before any work;
// near is the closest geometry in the frustum (clamped), far the range, the resolution
// the footprint's; a point light is a cube of six 90-degree grids whose faces cover every
// direction once, and its baked faces answer as exact segment rays do.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "cpvs/bake/bake.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/light_plan.h"
#include "cpvs/base/error.h"
#include "cpvs/eval/verify.h"
#include "cpvs/light/light.h"
#include "cpvs/query/shadow_query.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/scene/boxes.h"
#include "cpvs/scene/source.h"
#include "error_testing.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

using testing::inputErrorOf;

TEST(Light, BadLightsAreRefusedWithTheirNameAndWhatIsWrong) {
  const Vec3 lo{0, 0, 0}, hi{10, 10, 10};
  Light good;
  good.name = "lamp";
  good.position = {5, 8, 5};
  EXPECT_EQ(inputErrorOf([&] { checkLight(good, lo, hi, lightLabel(good, 3)); }), "");
  auto refused = [&](Light l, const std::string& part) {
    const std::string message = inputErrorOf([&] { checkLight(l, lo, hi, lightLabel(l, 3)); });
    EXPECT_NE(message.find("light 3 (lamp)"), std::string::npos) << message;
    EXPECT_NE(message.find(part), std::string::npos) << message;
  };
  Light l = good;
  l.position = {5, 40, 5};
  refused(l, "outside the scene's bounds");
  l = good;
  l.position.x = std::nan("");
  refused(l, "not finite");
  l = good;
  l.coneDeg = 0;
  refused(l, "cone");
  l.coneDeg = 90;
  refused(l, "cone");
  l = good;
  l.direction = {};
  refused(l, "direction");
  l = good;
  l.range = 3;
  l.near = 3;
  refused(l, "near");
  l = good;
  l.range = -1;
  refused(l, "range");
  l = good;
  l.colour = {1, -1, 1};
  refused(l, "colour");
  l = good;
  l.log2Resolution = 30;
  refused(l, "resolution");
  // A point light has no cone or direction to check; just outside the bounds is allowed.
  l = good;
  l.kind = LightKind::Point;
  l.coneDeg = 0;
  l.direction = {};
  l.position = {5, 10.5, 5};
  EXPECT_EQ(inputErrorOf([&] { checkLight(l, lo, hi, "p"); }), "");
  EXPECT_NE(inputErrorOf([] { checkLightCount(100000); }).find("at most 4096"), std::string::npos);
  EXPECT_NE(inputErrorOf([] { checkLightCount(0); }).find("no lights"), std::string::npos);
  EXPECT_EQ(inputErrorOf([] { checkLightCount(165); }), "");
}

TEST(Light, FlagsReadSpotAndPointLights) {
  const Light s = parseSpotFlag("1,2,3:0,-1,0.5:30:40");
  EXPECT_EQ(s.kind, LightKind::Spot);
  EXPECT_EQ(s.position, (Vec3{1, 2, 3}));
  EXPECT_EQ(s.direction, (Vec3{0, -1, 0.5}));
  EXPECT_EQ(s.coneDeg, 30);
  EXPECT_EQ(s.range, 40);
  EXPECT_EQ(parseSpotFlag("1,2,3:0,-1,0:30").range, 0);
  const Light p = parsePointFlag("4,5,6:12");
  EXPECT_EQ(p.kind, LightKind::Point);
  EXPECT_EQ(p.position, (Vec3{4, 5, 6}));
  EXPECT_EQ(p.range, 12);
  for (const char* bad : {"1,2,3", "1,2,3:0,-1,0", "1,2:0,-1,0:30", "1,2,3:0,-1,0:wide", "1,2,3:0,-1,0:30:4:5"})
    EXPECT_NE(inputErrorOf([&] { parseSpotFlag(bad); }), "") << bad;
  for (const char* bad : {"", "1,2", "1,2,3:4:5", "1,2,3:far"})
    EXPECT_NE(inputErrorOf([&] { parsePointFlag(bad); }), "") << bad;
}

// A lamp 10 above a ground quad, a box top 4 below it inside its cone and a tall box
// outside it: near is the box top, far the range, and the resolution the footprint's.
TEST(LightPlan, NearIsTheClosestGeometryInTheFrustum) {
  Scene scene;
  testing::appendQuad(scene, {-50, 0, -50}, {-50, 0, 50}, {50, 0, 50}, {50, 0, -50});
  appendBox(scene, {-1, 0, -1}, {1, 6, 1});     // its top 4 below the lamp
  appendBox(scene, {30, 0, 30}, {32, 9.5, 32});  // nearer, but outside the cone's frustum
  finalizeScene(scene);
  Light lamp;
  lamp.position = {0, 10, 0};
  lamp.direction = {0, -1, 0};
  lamp.coneDeg = 30;
  lamp.range = 20;
  const std::vector<LightGridPlan> plans = planLightGrids(scene, lamp, 0.05);
  ASSERT_EQ(plans.size(), 1u);
  const PerspectiveGrid& g = plans[0].grid;
  EXPECT_NEAR(plans[0].closest, 4, 1e-12);
  EXPECT_NEAR(g.near(), 4, 1e-12);
  EXPECT_EQ(g.far(), 20);
  EXPECT_NEAR(g.tanHalfFov(), std::tan(30 * M_PI / 180), 1e-15);
  EXPECT_EQ(plans[0].tanCone, g.tanHalfFov());
  // The frustum is 2 * 20 * tan 30° = 23.1 wide at far: 462 footprints of 0.05, so 512.
  EXPECT_EQ(g.log2Resolution(), 9);
  // The light's own near and resolution are kept; without a range, far reaches the
  // scene's farthest corner.
  lamp.near = 0.5;
  lamp.log2Resolution = 7;
  lamp.range = 0;
  const PerspectiveGrid own = planLightGrids(scene, lamp, 0).front().grid;
  EXPECT_EQ(own.near(), 0.5);
  EXPECT_EQ(own.log2Resolution(), 7);
  EXPECT_NEAR(own.far(), length(Vec3{50, 10, 50}) * 1.0001, 1e-9);
  // Geometry at the lamp (its own fixture) clamps near to far / kMaxDepthRatio.
  appendBox(scene, {-0.001, 9.999, -0.001}, {0.001, 10.001, 0.001});
  finalizeScene(scene);
  lamp.near = 0;
  lamp.range = 20;
  EXPECT_EQ(planLightGrids(scene, lamp, 0.05).front().grid.near(), 20 / kMaxDepthRatio);
  EXPECT_NE(inputErrorOf([&] { planLightGrids(scene, Light{}, 0); }).find("footprint"), std::string::npos);
  // The widest cone a light may have plans (tan 85° rounds a hair above the grid's limit).
  lamp.coneDeg = kMaxConeDeg;
  EXPECT_NEAR(planLightGrids(scene, lamp, 0.05).front().grid.tanHalfFov(), std::tan(85 * M_PI / 180), 1e-12);
}

TEST(LightPlan, APointLightsCubeFacesCoverEveryDirectionOnce) {
  Scene scene;
  appendBox(scene, {-10, -10, -10}, {10, 10, 10});
  finalizeScene(scene);
  Light bulb;
  bulb.kind = LightKind::Point;
  bulb.position = {1, 2, -3};
  bulb.log2Resolution = 6;
  const std::vector<LightGridPlan> faces = planLightGrids(scene, bulb, 0);
  ASSERT_EQ(faces.size(), 6u);
  std::mt19937_64 rng(9);
  std::normal_distribution<double> normal;
  for (int i = 0; i < 20000; ++i) {
    const Vec3 d{normal(rng), normal(rng), normal(rng)};
    const Vec3 p = bulb.position + d * 3;
    int inside = 0;
    for (const LightGridPlan& f : faces) {
      const Vec3 v = f.grid.voxelFromWorld(p);
      if (!(v.x >= 0 && v.x < 64 && v.y >= 0 && v.y < 64)) continue;
      ++inside;
      EXPECT_FALSE(f.grid.coneMissesTexel(uint64_t(v.x), uint64_t(v.y), f.tanCone)) << "a cube face's cone cuts no texel";
    }
    EXPECT_GE(inside, 1) << "direction " << i << " is in no face";
    const Vec3 v = faces[size_t(cubeFace(d))].grid.voxelFromWorld(p);
    EXPECT_TRUE(v.x >= 0 && v.x <= 64 && v.y >= 0 && v.y <= 64) << "cubeFace picks a face holding the point";
  }
}

// The six faces of a bulb in the procedural city, baked, against exact segment rays at
// surface points inside each face's frustum.
TEST(LightPlan, APointLightsBakedFacesEqualExactRays) {
  Scene scene = openScene("city:3");
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  Light bulb;
  bulb.kind = LightKind::Point;
  bulb.position = (lo + hi) * 0.5 + Vec3{0.05 * (hi.x - lo.x), 0.3 * (hi.y - lo.y), 0.02 * (hi.z - lo.z)};
  bulb.log2Resolution = 7;
  checkLight(bulb, lo, hi, "bulb");
  const RayScene rays(scene, (lo + hi) * 0.5);
  uint64_t samples = 0;
  for (const LightGridPlan& face : planLightGrids(scene, bulb, 0)) {
    const BakeScene prepared(scene, face.grid, face.tanCone, Renderer::Raster);
    const ShadowQuery query(face.grid, face.tanCone, PackedDag(bakeGrid(prepared, BakeOptions{})));
    // Inside the cone the face's square holds (45 degrees, less a margin of a few texels).
    const std::vector<SurfaceSample> inFace =
        sampleSpotSurfaces(scene, rays, ClosedMode::Auto, face.grid, 0.9, 1500, 4);
    const VerifyResult r = verifySamples(query, ClosedMode::Auto, rays, inFace);
    EXPECT_EQ(r.mismatchElsewhere, 0u);
    EXPECT_LT(r.fractionNearBoundary(), 0.05);
    samples += r.samples;
  }
  EXPECT_GT(samples, 3000u) << "the bulb must light the city around it";
}

}  // namespace
}  // namespace cpvs
