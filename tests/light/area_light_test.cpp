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
  for (BundleLight& l : bundle.lights) l.light.area = 2;  // area 1 gone
  bytes = encodeBundle(bundle, false);
  expectInputError([&] { decodeBundle(bytes.data(), bytes.size(), "gap.cpvs"); }, "area light 1 has no VPL");
}

// Soft visibility on the city's roofs and streets under a 12 x 12 panel, K = 64 VPLs at
// 128^3 (seed 002's resolution) and 256^3: against the same VPLs with exact rays, and
// against the emitter itself by Monte Carlo. The bounds are the errors measured (the
// worst 1 % are contact shadows beside walls, where a 128^3 grid's voxel is a unit wide).
class SoftShadows : public ::testing::TestWithParam<std::tuple<int, double>> {};

TEST_P(SoftShadows, AgreeWithExactVplsAndTheWholeEmitter) {
  const auto [log2R, p99Bound] = GetParam();
  const Scene scene = openScene("city:3:5");
  const AreaLight area = panel(64, log2R);
  const std::vector<Light> vpls = vplsOf(area, 1);
  const LightBundle bundle = bakeLights(scene, vpls, defaultFootprint(scene), BakeOptions{}, sceneHash(scene));
  // The bundle keeps the area numbers through its file.
  const std::vector<uint8_t> bytes = encodeBundle(bundle, true);
  const BundleQuery q(decodeBundle(bytes.data(), bytes.size(), "area.cpvs"));
  ASSERT_EQ(q.areaCount(), 1u);
  ASSERT_EQ(q.vplsOf(0).size(), 64u);

  const RayScene rays(scene, area.centre);
  const Vec3 ne = area.normal();
  auto exactlySeen = [&](const Vec3& x, const Vec3& p, const Vec3& n) {
    const Vec3 from = p + n * 1e-4;
    const Vec3 d = x - from;
    const double len = length(d);
    return !rays.occluded(from, d / len, 0.0, len);
  };
  // Points on surfaces facing up, under the panel (within 30 units of its centre), that a
  // camera can see: not the ground inside a building (the city's stand on it, their
  // floors below it), whose voxels the bake may fill either way.
  std::vector<SurfaceSample> points;
  for (const SurfaceSample& s : sampleSurfaces(scene, rays, ClosedMode::Auto, {0, -1, 0}, 40000, 5)) {
    const Vec3 d = s.point - area.centre;
    const bool covered = rays.closedNesting(s.point + s.normal * 1e-4, {0, 1, 0}, 1e4, ClosedMode::Auto) > 0;
    if (s.normal.y > 0.5 && std::abs(d.x) < 30 && std::abs(d.z) < 30 && !covered) points.push_back(s);
    if (points.size() == 600) break;
  }
  ASSERT_GE(points.size(), 300u);
  std::vector<double> voxelError, sampleError, wholeError, fewVplError;
  const std::vector<Light> few = vplsOf(panel(4, 7), 1);
  const int m = 64;  // 64 x 64 stratified points on the panel: 4,096 rays
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> unit(0, 1);
  uint64_t penumbra = 0;
  for (const SurfaceSample& s : points) {
    // K VPLs with exact rays, the same weights.
    auto exactVpls = [&](const std::vector<Light>& set) {
      double sum = 0, lit = 0;
      for (const Light& l : set) {
        const double w = vplWeight(l.position, l.direction, s.point, s.normal);
        sum += w;
        if (w > 0 && exactlySeen(l.position, s.point, s.normal)) lit += w;
      }
      return sum > 0 ? lit / sum : 0.0;
    };
    const double vplsExact = exactVpls(vpls);
    double sum = 0, lit = 0;
    for (int i = 0; i < m; ++i)
      for (int j = 0; j < m; ++j) {
        const Vec3 x = area.centre + area.edgeU * ((i + unit(rng)) / m - 0.5) + area.edgeV * ((j + unit(rng)) / m - 0.5);
        const double w = vplWeight(x, ne, s.point, s.normal);
        sum += w;
        if (w > 0 && exactlySeen(x, s.point, s.normal)) lit += w;
      }
    const double truth = sum > 0 ? lit / sum : 0.0;
    const double baked = q.softVisibility(0, s.point, s.normal);
    voxelError.push_back(std::abs(baked - vplsExact));
    sampleError.push_back(std::abs(vplsExact - truth));
    wholeError.push_back(std::abs(baked - truth));
    fewVplError.push_back(std::abs(exactVpls(few) - truth));
    penumbra += truth > 0.05 && truth < 0.95;
  }
  auto mean = [](std::vector<double> v) {
    double s = 0;
    for (double x : v) s += x;
    return s / double(v.size());
  };
  auto p99 = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[size_t(0.99 * double(v.size() - 1))];
  };
  std::printf("%d^3: %zu points, %llu in penumbra: mean error baked %.4f (p99 %.4f), K VPLs exact %.4f (p99 %.4f), voxels %.4f\n",
              1 << log2R, points.size(), static_cast<unsigned long long>(penumbra), mean(wholeError), p99(wholeError),
              mean(sampleError), p99(sampleError), mean(voxelError));
  EXPECT_GT(penumbra, points.size() / 10) << "the points must see soft shadow";
  EXPECT_LE(mean(wholeError), 0.02);
  EXPECT_LE(p99(wholeError), p99Bound);
  EXPECT_LE(mean(voxelError), 0.02);
  EXPECT_LT(mean(sampleError), 0.5 * mean(fewVplError)) << "64 VPLs sample the emitter better than 4";
}

INSTANTIATE_TEST_SUITE_P(Resolutions, SoftShadows, ::testing::Values(std::tuple{7, 0.2}, std::tuple{8, 0.1}));

}  // namespace
}  // namespace cpvs
