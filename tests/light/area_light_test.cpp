// Area lights as VPL bundles (seed 002, NOTES §3.5): the VPLs' placement, the refusals,
// the area numbers in the bundle file, and soft visibility against the same VPLs with
// exact rays (the voxel error) and against a Monte Carlo integral over the rectangle with
// 4,096 stratified rays per point (the whole error, and the sampling error alone).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <tuple>

#include "cpvs/bake/bake_lights.h"
#include "cpvs/eval/surface_sampling.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/light/area_light.h"
#include "cpvs/query/bundle_query.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/scene/source.h"
#include "area_testing.h"
#include "error_testing.h"

namespace cpvs {
namespace {

using testing::expectInputError;

AreaLight panel(uint32_t vpls, int log2R, uint64_t seed = 1) {
  AreaLight a;
  a.name = "panel";
  a.centre = {36, 66, 36};  // above the roofs of city:3:5 (its tallest reach about 58)
  a.edgeU = {12, 0, 0};
  a.edgeV = {0, 0, 12};  // U x V points down: it shines on the city
  a.vpls = vpls;
  a.log2Resolution = log2R;
  a.seed = seed;
  a.intensity = 8;
  return a;
}

TEST(AreaLight, VplsSampleTheRectangleEvenlyFromASeed) {
  const AreaLight a = panel(64, 7);
  const std::vector<Light> v = vplsOf(a, 3);
  ASSERT_EQ(v.size(), 64u);
  int quadrant[4] = {0, 0, 0, 0};
  double intensity = 0;
  for (const Light& l : v) {
    EXPECT_EQ(l.kind, LightKind::Point);
    EXPECT_EQ(l.area, 3u);
    EXPECT_EQ(l.log2Resolution, 7);
    EXPECT_EQ(l.direction, (Vec3{0, -1, 0}));
    const Vec3 d = l.position - a.centre;
    EXPECT_LE(std::abs(d.x), 6.0);
    EXPECT_LE(std::abs(d.z), 6.0);
    EXPECT_LT(d.y, 0.0);  // lifted off the emitter towards where it shines
    EXPECT_GT(d.y, -0.01);
    ++quadrant[(d.x > 0) + 2 * (d.z > 0)];
    intensity += l.intensity;
  }
  EXPECT_DOUBLE_EQ(intensity, 8.0);
  for (int q : quadrant) EXPECT_NEAR(q, 16, 2) << "a Halton set covers the rectangle evenly";
  EXPECT_EQ(vplsOf(a, 3)[17].position, v[17].position);            // deterministic
  EXPECT_NE(vplsOf(panel(64, 7, 2), 3)[17].position, v[17].position);  // another seed, another set
  // The weight: cosines at both ends over the squared distance; nothing behind either.
  EXPECT_DOUBLE_EQ(vplWeight({0, 2, 0}, {0, -1, 0}, {0, 0, 0}, {0, 1, 0}), 0.25);
  EXPECT_EQ(vplWeight({0, 2, 0}, {0, 1, 0}, {0, 0, 0}, {0, 1, 0}), 0.0);
  EXPECT_EQ(vplWeight({0, 2, 0}, {0, -1, 0}, {0, 0, 0}, {0, -1, 0}), 0.0);
  EXPECT_DOUBLE_EQ(vplWeight({0, 2, 0}, {0, -1, 0}, {0, 0, 0}, {}), 0.25);
}

// Each VPL's cube is turned by its own seeded rotation: orthonormal, right-handed, a face
// along the emitter's normal but for a sub-texel tilt, unlike its neighbours', the same
// for a seed; face f looks along its own axes and the face a
// direction falls in is the one whose axis it is nearest (the largest dot product).
TEST(AreaLight, VplCubesAreRolledFromTheSeed) {
  AreaLight a = panel(16, 7);
  const std::vector<Light> v = vplsOf(a, 1);
  for (size_t i = 0; i < v.size(); ++i) {
    const std::array<Vec3, 3>& c = v[i].cube;
    EXPECT_TRUE(isOrthonormalCube(c));
    EXPECT_NEAR(dot(cross(c[0], c[1]), c[2]), 1.0, 1e-12) << "a rotation, not a mirror";
    // Its -y face looks along the emitter's normal within a texel's angle either way (1/128 about two axes).
    EXPECT_GT(dot(c[1], a.normal()), -1.0);
    EXPECT_LT(dot(c[1], a.normal()), -std::cos(std::sqrt(2.0) / 128));
    if (i > 0) {
      EXPECT_NE(c[0], v[i - 1].cube[0]);
    }
    EXPECT_EQ(vplsOf(a, 1)[i].cube, c);
    std::mt19937_64 rng(i);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int k = 0; k < 200; ++k) {
      const Vec3 d{u(rng), u(rng), u(rng)};
      const int face = cubeFace(d, c);
      const LightFrame f = cubeFaceFrame(face, c);
      for (int other = 0; other < 6; ++other) EXPECT_GE(dot(d, f.dir), dot(d, cubeFaceFrame(other, c).dir));
      EXPECT_NEAR(dot(cross(f.u, f.v), f.dir), dot(cross(cubeFaceFrame(face, kAxisCube).u, cubeFaceFrame(face, kAxisCube).v),
                                                 cubeFaceFrame(face, kAxisCube).dir), 1e-12);
      EXPECT_EQ(cubeFace(d, kAxisCube), cubeFace(d));
    }
  }
  a.roll = false;
  for (const Light& l : vplsOf(a, 1)) EXPECT_EQ(l.cube, kAxisCube);
  for (int face = 0; face < 6; ++face)
    EXPECT_EQ(cubeFaceFrame(face, kAxisCube), LightFrame::fromDirection(cubeFaceAxis(face)));
  // Ties between faces go to the first, as before.
  EXPECT_EQ(cubeFace({1, 1, 0}, kAxisCube), 0);
  EXPECT_EQ(cubeFace({0, 0, 0}, kAxisCube), 0);
}

TEST(AreaLight, BadAreaLightsAreRefused) {
  const Vec3 lo{0, 0, 0}, hi{60, 60, 60};
  AreaLight a = panel(64, 7);
  a.edgeV = {24, 0, 0};  // parallel to U
  expectInputError([&] { checkAreaLight(a, lo, hi, "area 1"); }, "no area");
  a = panel(0, 7);
  expectInputError([&] { checkAreaLight(a, lo, hi, "area 1"); }, "1 to 1024");
  a = panel(64, 3);
  expectInputError([&] { checkAreaLight(a, lo, hi, "area 1"); }, "VPL resolution");
  a = panel(64, 7);
  a.centre = {500, 40, 30};
  expectInputError([&] { checkAreaLight(a, lo, hi, "area 1"); }, "outside the scene's bounds");
  expectInputError([] { parseAreaLightFlag("1,2,3:1,0,0"); }, "3 to 5 fields");
  expectInputError([] { parseAreaLightFlag("1,2,3:1,0,0:0,0,1:0"); }, "VPL count");
  expectInputError([] { parseAreaLightFlag("1,2,3:1,0,0:0,0,1:16:8"); }, "16 to 1024");
  const AreaLight parsed = parseAreaLightFlag("1,2,3:1,0,0:0,0,1:16:256");
  EXPECT_EQ(parsed.vpls, 16u);
  EXPECT_EQ(parsed.log2Resolution, 8);
  EXPECT_EQ(parsed.edgeV, (Vec3{0, 0, 1}));
}

// A bundle's area lights are numbered from 1 in its file; a number without its VPLs is
// refused when the file is read.
TEST(AreaLight, TheBundleFileKeepsTheAreaNumbers) {
  const Scene scene = openScene("city:3:5");
  std::vector<Light> lights = vplsOf(panel(2, 4), 1);
  for (Light& l : vplsOf(panel(3, 4, 7), 2)) lights.push_back(l);
  LightBundle bundle = bakeLights(scene, lights, defaultFootprint(scene), BakeOptions{}, sceneHash(scene));
  std::vector<uint8_t> bytes = encodeBundle(bundle, false);
  const BundleQuery q(decodeBundle(bytes.data(), bytes.size(), "two.cpvs"));
  ASSERT_EQ(q.areaCount(), 2u);
  EXPECT_EQ(q.vplsOf(0), (std::vector<uint32_t>{0, 1}));
  EXPECT_EQ(q.vplsOf(1), (std::vector<uint32_t>{2, 3, 4}));
  // The rolled cubes come back from the grids' frames.
  const LightBundle back = decodeBundle(bytes.data(), bytes.size(), "two.cpvs");
  for (size_t i = 0; i < lights.size(); ++i) EXPECT_EQ(back.lights[i].light.cube, lights[i].cube) << i;
  // Six grids that are not a cube's faces are refused.
  LightBundle bent = bundle;
  bent.grids[1] = bent.grids[3];
  bytes = encodeBundle(bent, false);
  expectInputError([&] { decodeBundle(bytes.data(), bytes.size(), "bent.cpvs"); }, "not a cube's faces");
  // An area light's VPLs are consecutive lights (a soft lookup walks them from the first).
  LightBundle mixed = bundle;
  mixed.lights[0].light.area = 2;  // 2, 1, 2, 2, 2
  bytes = encodeBundle(mixed, false);
  expectInputError([&] { decodeBundle(bytes.data(), bytes.size(), "mixed.cpvs"); }, "not consecutive");
  for (BundleLight& l : bundle.lights) l.light.area = 2;  // area 1 gone
  bytes = encodeBundle(bundle, false);
  expectInputError([&] { decodeBundle(bytes.data(), bytes.size(), "gap.cpvs"); }, "area light 1 has no VPL");
}

// Soft visibility on the city's roofs and streets under a 12 x 12 panel, K = 64 VPLs at
// 128^3 (seed 002's resolution) and 256^3, and on the city turned 30 degrees about its
// centre (the panel with it: walls no VPL cube is aligned with): against the same VPLs
// with exact rays, and against the emitter itself by Monte Carlo. The bounds are the
// issue's targets (measured: p99 0.093 and 0.097 at 128^3, 0.055 at 256^3); the worst
// 1 % are contact shadows beside walls, where a 128^3 grid's voxel is a unit wide.
class SoftShadows : public ::testing::TestWithParam<std::tuple<int, double, double>> {};

TEST_P(SoftShadows, AgreeWithExactVplsAndTheWholeEmitter) {
  const auto [log2R, degrees, p99Bound] = GetParam();
  Scene scene = openScene("city:3:5");
  AreaLight area = panel(64, log2R);
  const double c = std::cos(degrees * M_PI / 180), s = std::sin(degrees * M_PI / 180);
  auto turn = [&](const Vec3& v) { return Vec3{c * v.x - s * v.z, v.y, s * v.x + c * v.z}; };
  for (Vec3& p : scene.positions) p = area.centre + turn(p - area.centre);
  area.edgeU = turn(area.edgeU);
  area.edgeV = turn(area.edgeV);
  const std::vector<Light> vpls = vplsOf(area, 1);
  const LightBundle bundle = bakeLights(scene, vpls, defaultFootprint(scene), BakeOptions{}, sceneHash(scene));
  // The bundle keeps the area numbers through its file.
  const std::vector<uint8_t> bytes = encodeBundle(bundle, true);
  const BundleQuery q(decodeBundle(bytes.data(), bytes.size(), "area.cpvs"));
  ASSERT_EQ(q.areaCount(), 1u);
  ASSERT_EQ(q.vplsOf(0).size(), 64u);

  const RayScene rays(scene, area.centre);
  // Surfaces facing the panel within 30 units of its centre across, that a camera can see.
  const std::vector<SurfaceSample> points = testing::pointsUnderArea(scene, rays, area, 30, 600, 5);
  ASSERT_GE(points.size(), 300u);
  std::vector<double> voxelError, sampleError, wholeError, fewVplError;
  AreaLight fourVpls = area;
  fourVpls.vpls = 4;
  const std::vector<Light> few = vplsOf(fourVpls, 1);
  uint64_t penumbra = 0;
  for (size_t k = 0; k < points.size(); ++k) {
    const Vec3 &p = points[k].point, &n = points[k].normal;
    const double vplsExact = testing::exactVplVisibility(rays, vpls, p, n);
    const double truth = testing::emitterVisibility(rays, area, p, n, 64, k);  // 4,096 rays
    const double baked = q.softVisibility(0, p, n);
    voxelError.push_back(std::abs(baked - vplsExact));
    sampleError.push_back(std::abs(vplsExact - truth));
    wholeError.push_back(std::abs(baked - truth));
    fewVplError.push_back(std::abs(testing::exactVplVisibility(rays, few, p, n) - truth));
    penumbra += truth > 0.05 && truth < 0.95;
  }
  using testing::meanOf, testing::p99Of;
  std::printf("%d^3, turned %g degrees: %zu points, %llu in penumbra: mean error baked %.4f (p99 %.4f), K VPLs exact %.4f (p99 %.4f), voxels %.4f\n",
              1 << log2R, degrees, points.size(), static_cast<unsigned long long>(penumbra), meanOf(wholeError), p99Of(wholeError),
              meanOf(sampleError), p99Of(sampleError), meanOf(voxelError));
  EXPECT_GT(penumbra, points.size() / 10) << "the points must see soft shadow";
  EXPECT_LE(meanOf(wholeError), 0.02);
  EXPECT_LE(p99Of(wholeError), p99Bound);
  EXPECT_LE(meanOf(voxelError), 0.02);
  EXPECT_LT(meanOf(sampleError), 0.5 * meanOf(fewVplError)) << "64 VPLs sample the emitter better than 4";
}

INSTANTIATE_TEST_SUITE_P(Resolutions, SoftShadows,
                         ::testing::Values(std::tuple{7, 0.0, 0.1}, std::tuple{7, 30.0, 0.1}, std::tuple{8, 0.0, 0.1}));

}  // namespace
}  // namespace cpvs
