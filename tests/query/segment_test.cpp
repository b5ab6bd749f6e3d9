// Light along a segment (sun shafts): the hierarchical walk against a dense voxel-by-voxel
// walk on small grids, the lit stretches against exact shadow rays on real scenes, and the
// medium's closed forms against their limits and a quadrature.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>
#include <random>

#include "cpvs/eval/camera.h"
#include "cpvs/query/segment_walk.h"
#include "cpvs/query/shadow_query.h"
#include "cpvs/raytrace/visibility.h"
#include "cpvs/scene/source.h"
#include "dag_testing.h"
#include "error_testing.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

using testing::expectInputError;

struct Piece {
  double t0, t1;
  bool shadowed;
};

// Adjacent pieces of one value joined and empty ones dropped: the segment's visibility as
// a step function of t.
std::vector<Piece> steps(const std::vector<Piece>& pieces) {
  std::vector<Piece> out;
  for (const Piece& p : pieces) {
    if (p.t1 <= p.t0) continue;
    if (!out.empty() && out.back().shadowed == p.shadowed && out.back().t1 == p.t0) out.back().t1 = p.t1;
    else out.push_back(p);
  }
  return out;
}

// The grid's value of any voxel, by ShadowQuery's rules for the sun: in front and beside
// the grid lit, beyond its far side the last slice.
bool referenceShadowed(const PackedDag& dag, int64_t x, int64_t y, int64_t z) {
  const int64_t R = int64_t(1) << dag.log2Resolution();
  if (x < 0 || y < 0 || x >= R || y >= R || z < 0) return false;
  return dag.voxelShadowed(uint64_t(x), uint64_t(y), uint64_t(std::min(z, R - 1)));
}

// The reference: one voxel at a time over the whole segment, outside the grid as well.
// Voxel boundaries are the planes (k - p) / d, as the walk computes them.
std::vector<Piece> denseWalk(const PackedDag& dag, const Vec3& o, const Vec3& e, std::vector<std::array<int64_t, 4>>* voxels) {
  const double p[3] = {o.x, o.y, o.z}, d[3] = {e.x - o.x, e.y - o.y, e.z - o.z};
  int64_t v[3];
  for (int a = 0; a < 3; ++a) v[a] = d[a] == 0 ? int64_t(std::floor(p[a])) : voxelOnAxisAt(p[a], d[a], 0);
  std::vector<Piece> out;
  double t = 0;
  while (true) {
    double next = 1;
    for (int a = 0; a < 3; ++a)
      if (d[a] != 0) next = std::min(next, (double(d[a] > 0 ? v[a] + 1 : v[a]) - p[a]) / d[a]);
    const bool shadowed = referenceShadowed(dag, v[0], v[1], v[2]);
    out.push_back({t, std::max(t, next), shadowed});
    if (voxels && next > t) voxels->push_back({v[0], v[1], v[2], int64_t((t + next) * 0.5 * (1 << 30))});
    if (next >= 1) break;
    t = std::max(t, next);
    for (int a = 0; a < 3; ++a)
      if (d[a] != 0) v[a] = voxelOnAxisAt(p[a], d[a], t);
  }
  return out;
}

// The hierarchical walk visits the voxels a dense walk visits, block by block: the same
// step function of t to the bit, every voxel of the dense walk inside the block that
// covers it, and far fewer pieces. Segments start and end anywhere around the grid, run
// along axes and through voxel corners.
TEST(SegmentWalk, VisitsTheVoxelsOfADenseWalkABlockAtATime) {
  for (const auto& [log2R, closed, seed] : {std::tuple{6, true, 1u}, std::tuple{6, false, 2u}, std::tuple{7, true, 3u}}) {
    const uint32_t R = 1u << log2R;
    const TexelSlices slices = testing::syntheticSlices(R, closed, seed);
    const PackedDag dag(testing::buildTiled(slices, log2R, log2R, UndefinedRule::New, true, CompressMode::TopDown,
                                            HashKind::Xxh3));
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> coord(-0.3 * R, 1.3 * R);
    std::uniform_int_distribution<int> corner(-2, int(R) + 2);
    uint64_t densePieces = 0, walkPieces = 0, shadowedSteps = 0, litSteps = 0;
    for (int i = 0; i < 3000; ++i) {
      Vec3 o{coord(rng), coord(rng), coord(rng)}, e{coord(rng), coord(rng), coord(rng)};
      if (i % 5 == 1) e.y = o.y;                                              // in a plane of x and z
      if (i % 5 == 2) e.x = o.x, e.z = o.z;                                   // along y
      if (i % 5 == 3) o = {double(corner(rng)), double(corner(rng)), double(corner(rng))}, e = o + Vec3{7, 7, 7};  // corners
      if (i % 5 == 4) e = o;                                                  // a point
      std::vector<std::array<int64_t, 4>> voxels;
      const std::vector<Piece> dense = denseWalk(dag, o, e, &voxels);
      std::vector<Piece> walked;
      std::vector<SegmentPiece> blocks;
      walkSegment(dag, o, e, [&](const SegmentPiece& s) {
        ASSERT_GE(s.t0, walked.empty() ? 0.0 : walked.back().t1);
        walked.push_back({s.t0, s.t1, s.shadowed});
        blocks.push_back(s);
      });
      ASSERT_FALSE(walked.empty());
      EXPECT_EQ(walked.front().t0, 0.0);
      EXPECT_EQ(walked.back().t1, 1.0);
      const std::vector<Piece> a = steps(dense), b = steps(walked);
      ASSERT_EQ(a.size(), b.size()) << "segment " << i;
      for (size_t k = 0; k < a.size(); ++k) {
        EXPECT_EQ(a[k].t0, b[k].t0) << "segment " << i << " step " << k;
        EXPECT_EQ(a[k].t1, b[k].t1) << "segment " << i << " step " << k;
        EXPECT_EQ(a[k].shadowed, b[k].shadowed) << "segment " << i << " step " << k;
        (a[k].shadowed ? shadowedSteps : litSteps)++;
      }
      // Each voxel the dense walk crosses (inside the grid) lies in the block of the piece
      // that covers the middle of its stretch.
      for (const auto& [x, y, z, mid] : voxels) {
        if (x < 0 || y < 0 || x >= int64_t(R) || y >= int64_t(R) || z < 0) continue;
        const double t = double(mid) / double(1 << 30);
        const auto at = std::find_if(blocks.begin(), blocks.end(), [&](const SegmentPiece& s) { return s.t0 <= t && t <= s.t1 && s.inGrid; });
        ASSERT_NE(at, blocks.end()) << "segment " << i;
        const int64_t side = int64_t(1) << at->log2Side, depth = int64_t(1) << at->log2Depth;
        const int64_t zz = std::min<int64_t>(z, R - 1);
        EXPECT_TRUE(x >= at->x && x < at->x + side && y >= at->y && y < at->y + side && zz >= at->z && zz < at->z + depth)
            << "segment " << i << ": voxel " << x << "," << y << "," << z << " outside its block";
      }
      densePieces += dense.size();
      walkPieces += walked.size();
    }
    EXPECT_GT(shadowedSteps, 500u);
    EXPECT_GT(litSteps, 500u);
    EXPECT_LT(double(walkPieces), 0.5 * double(densePieces)) << "the walk did not skip homogeneous blocks";
  }
}

double attenuatedBySteps(double sigma, double u0, double u1, int n) {
  double sum = 0, h = (u1 - u0) / n;
  for (int i = 0; i < n; ++i) sum += std::exp(-sigma * (u0 + (i + 0.5) * h)) * h;
  return sum;
}

TEST(Medium, ClosedFormsAndTheirLimits) {
  // The attenuated length against a midpoint quadrature, and its limit sigma -> 0.
  for (double sigma : {0.0, 1e-9, 0.01, 0.5, 3.0})
    for (auto [u0, u1] : {std::pair{0.0, 1.0}, std::pair{2.5, 7.0}, std::pair{0.0, 40.0}})
      EXPECT_NEAR(attenuatedLength(sigma, u0, u1), attenuatedBySteps(sigma, u0, u1, 200000),
                  1e-8 * std::max(1.0, u1 - u0));
  EXPECT_EQ(attenuatedLength(0, 2, 5), 3.0);
  EXPECT_NEAR(attenuatedLength(1e-12, 2, 5), 3.0, 1e-9);
  // Henyey-Greenstein: 1/(4 pi) when isotropic, a distribution over the sphere for any g.
  EXPECT_DOUBLE_EQ(henyeyGreenstein(0, 0.3), 1 / (4 * std::numbers::pi));
  for (double g : {-0.9, -0.3, 0.0, 0.5, 0.95}) {
    double sum = 0;
    const int n = 400000;
    for (int i = 0; i < n; ++i) sum += henyeyGreenstein(g, -1 + (i + 0.5) * 2.0 / n) * 2 * std::numbers::pi * 2.0 / n;
    EXPECT_NEAR(sum, 1.0, 1e-4) << "g " << g;
  }
  EXPECT_GT(henyeyGreenstein(0.8, 1), henyeyGreenstein(0.8, -1));  // forward scattering
  // A wholly lit segment: sigma_s p (1 - e^(-sigma d)) / sigma, exactly.
  const Medium m{0.02, 0.01, 0.4};
  const SegmentLight s = scatterAlong({{0.0, 50.0}}, 50.0, m, 0.7);
  EXPECT_NEAR(s.inScattering, 0.02 * henyeyGreenstein(0.4, 0.7) * -std::expm1(-0.03 * 50) / 0.03, 1e-15);
  EXPECT_DOUBLE_EQ(s.transmittance, std::exp(-0.03 * 50));
  EXPECT_EQ(s.litLength, 50.0);
}

TEST(Medium, BadMediaAreRefused) {
  expectInputError([] { checkMedium({-0.1, 0, 0}); }, "scattering");
  expectInputError([] { checkMedium({0.1, std::nan(""), 0}); }, "absorption");
  expectInputError([] { checkMedium({0.1, 0, 1.0}); }, "between -1 and 1");
  expectInputError([] { checkMedium({0.1, 0, -1.0}); }, "between -1 and 1");
  expectInputError([] { parseMedium("0.1", "--medium"); }, "SIGMA_S,SIGMA_A");
  expectInputError([] { parseMedium("0.1,0.2,x", "--medium"); }, "--medium");
  EXPECT_EQ(parseMedium("0.1,0.2,0.5", "--medium").g, 0.5);
}

// On real scenes the lit stretches of view segments are exact for the voxelization (each
// point of the segment as the voxel it lies in answers) and differ from exact shadow rays
// only within a voxel of a shadow boundary the segment crosses.
TEST(SunShafts, LitStretchesAgreeWithShadowRaysUpToTheBoundaryVoxels) {
  struct Case {
    const char* name;
    const char* relative;  // under shared/scenes, or "" for the procedural city
    Vec3 sun;
  };
  for (const Case& c : {Case{"city", "", {0.35, -1, 0.25}}, Case{"shouse", "openarena/oa_shouse.obj", {0.4, -1, 0.3}}}) {
    if (*c.relative && testing::sharedScenesDir().empty()) continue;  // the city alone without shared/scenes
    const Scene scene = *c.relative ? openScene(testing::sharedScenesDir() + "/" + c.relative) : openScene("city:3:5");
    const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection(c.sun), 8);
    const RayScene rays(scene, grid.origin);
    BakeOptions options;
    const ShadowQuery q(grid, PackedDag(testing::bakeWith(scene, grid, options)));
    const double diagonal = std::sqrt(grid.texelSize() * grid.texelSize() * 2 + grid.sliceSize() * grid.sliceSize());
    // View segments as a camera sees them: from eyes above the roofs to the first surface
    // (or out of the scene's box), so that none runs inside a closed part, whose voxels
    // the bake may fill either way.
    Vec3 lo, hi;
    sceneBounds(scene, lo, hi);
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> unit(0, 1);
    double worstExcess = 0, sumError = 0, sumLength = 0;
    uint64_t voxelDiffer = 0, crossings = 0;
    for (int i = 0; i < 600; ++i) {
      const Vec3 a{lo.x + unit(rng) * (hi.x - lo.x), hi.y + unit(rng) * 0.2 * (hi.y - lo.y), lo.z + unit(rng) * (hi.z - lo.z)};
      const Vec3 dir = normalize(Vec3{unit(rng) - 0.5, -0.05 - 0.5 * unit(rng), unit(rng) - 0.5});
      SurfaceHit hit;
      if (!firstSurface(scene, rays, a, dir, hit)) continue;
      const Vec3 b = hit.point;
      const double len = length(b - a);
      const auto lit = q.litStretches(a, b);
      auto litAt = [&](double u) {
        for (const auto& [u0, u1] : lit)
          if (u >= u0 && u < u1) return true;
        return false;
      };
      // Exact for the voxelization: sample points away from the stretch ends.
      const int n = 4096;
      double exactLit = 0;
      int transitions = 0;
      bool previous = false;
      for (int k = 0; k < n; ++k) {
        const double u = (k + 0.5) / n * len;
        const Vec3 p = a + (b - a) * ((k + 0.5) / n);
        const VoxelCoord v{int64_t(std::floor(grid.voxelFromWorld(p).x)), int64_t(std::floor(grid.voxelFromWorld(p).y)),
                           int64_t(std::floor(grid.voxelFromWorld(p).z))};
        bool nearEnd = false;
        for (const auto& [u0, u1] : lit) nearEnd |= std::abs(u - u0) < 1e-9 * len || std::abs(u - u1) < 1e-9 * len;
        if (!nearEnd) voxelDiffer += litAt(u) == q.voxelShadowed(v);
        const bool ray = exactlyLit(rays, grid, p);
        exactLit += ray ? len / n : 0;
        if (k > 0 && ray != previous) ++transitions;
        previous = ray;
      }
      double cpvsLit = 0;
      for (const auto& [u0, u1] : lit) cpvsLit += u1 - u0;
      const double error = std::abs(cpvsLit - exactLit);
      // Each boundary either side crosses costs at most a voxel's diagonal (twice: the
      // voxel of the boundary and the normal-offset-free voxel rule), plus the
      // quadrature's own step per exact transition.
      const double bound = double(2 * (transitions + 2 * lit.size())) * diagonal + double(transitions + 2) * len / n;
      worstExcess = std::max(worstExcess, error - bound);
      sumError += error;
      sumLength += len;
      crossings += transitions;
      const SegmentLight s = q.inScattering(a, b, Medium{0.01, 0.005, 0.3});
      EXPECT_NEAR(s.litLength, cpvsLit, 1e-9 * len);
      EXPECT_LE(s.inScattering, 0.01 * henyeyGreenstein(0.3, 1) * len);
    }
    EXPECT_EQ(voxelDiffer, 0u) << c.name;
    EXPECT_LE(worstExcess, 0.0) << c.name;
    EXPECT_GT(crossings, 50u) << c.name << ": the segments crossed too few shadows to test anything";
    EXPECT_LT(sumError / sumLength, 0.02) << c.name;
    std::printf("%s: %llu shadow boundaries crossed, lit length off by %.3g%% of the length on average\n", c.name,
                static_cast<unsigned long long>(crossings), 100 * sumError / sumLength);
  }
}

// Outside any shadow (above the scene, or outside the grid) a segment is lit end to end
// and scatters the closed form; a spot light's grid refuses segments.
TEST(SunShafts, AnUnshadowedSegmentScattersTheClosedForm) {
  const Scene scene = openScene("city:3:5");
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection({0, -1, 0}), 7);
  const ShadowQuery q(grid, PackedDag(testing::bakeWith(scene, grid, BakeOptions{})));
  // Above the roofs, straight down: nothing between the sun and the segment.
  const Vec3 a = grid.worldFromVoxel({10, 20, 0.5}), b = grid.worldFromVoxel({100, 90, 1.5});
  const double d = length(b - a);
  const Medium m{0.05, 0.02, 0.0};
  const SegmentLight s = q.inScattering(a, b, m);
  EXPECT_DOUBLE_EQ(s.length, d);
  EXPECT_NEAR(s.litLength, d, 1e-9 * d);
  EXPECT_NEAR(s.inScattering, 0.05 / (4 * std::numbers::pi) * -std::expm1(-0.07 * d) / 0.07, 1e-12);
  const SegmentLight clear = q.inScattering(a, b, Medium{0.05, 0, 0});
  EXPECT_NEAR(clear.transmittance, std::exp(-0.05 * d), 1e-15);
  // Wholly beside the grid: lit.
  const Vec3 far1 = grid.worldFromVoxel({-50, 10, 10}), far2 = grid.worldFromVoxel({-10, 100, 60});
  EXPECT_EQ(q.litStretches(far1, far2).size(), 1u);
  expectInputError([&] { q.inScattering(a, b, Medium{-1, 0, 0}); }, "scattering");
}

}  // namespace
}  // namespace cpvs
