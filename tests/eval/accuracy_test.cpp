// The accuracy measurements: the plain shadow-map baseline against a brute-force reference,
// the distance-to-boundary estimate on a case with a known answer, mismatch rates that
// fall with resolution, and `cpvs accuracy`'s files and its refusals of bad input.
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "cpvs/scene/boxes.h"
#include "cpvs/base/error.h"
#include "cpvs/scene/procedural_city.h"
#include "cpvs/eval/accuracy.h"
#include "cpvs/eval/accuracy_report.h"
#include "cpvs/eval/render.h"
#include "cpvs/eval/shadow_map.h"
#include "cpvs/eval/verify.h"
#include "cpvs/raytrace/visibility.h"
#include "cpvs/scene/source.h"
#include "process_testing.h"

namespace cpvs {
namespace {

namespace fs = std::filesystem;


// A ground slab from -10 to 10 in x and z, top at y = 0, and a box floating above it over
// [-1, 1] x [1, 3] x [-1, 1]: under a light straight down, its shadow on the ground is the
// square |x|, |z| <= 1 with crisp edges.
Scene floatingBox() {
  Scene s;
  s.name = "floating box";
  appendBox(s, {-10, -1, -10}, {10, 0, 10});
  appendBox(s, {-1, 1, -1}, {1, 3, 1});
  finalizeScene(s);
  return s;
}

// Nearest hit of a ray against every triangle, in double precision; `ambiguous` when the
// ray passes within a hair of a triangle's edge (float and double may then disagree).
double bruteForceHit(const Scene& scene, const Vec3& from, const Vec3& dir, bool& ambiguous) {
  double best = std::numeric_limits<double>::infinity();
  ambiguous = false;
  for (size_t t = 0; t < scene.triangleCount(); ++t) {
    const Vec3 a = scene.vertex(t, 0), b = scene.vertex(t, 1), c = scene.vertex(t, 2);
    const Vec3 e1 = b - a, e2 = c - a, p = cross(dir, e2);
    const double det = dot(e1, p);
    if (std::abs(det) < 1e-300) continue;
    const Vec3 s = from - a;
    const double u = dot(s, p) / det;
    const Vec3 q = cross(s, e1);
    const double v = dot(dir, q) / det, w = 1 - u - v, dist = dot(e2, q) / det;
    const double m = std::min({u, v, w});
    if (dist > 0 && std::abs(m) < 1e-5) ambiguous = true;
    if (m >= 0 && dist > 0) best = std::min(best, dist);
  }
  return best;
}

// Every texel of the packet-rendered map equals the double-precision brute force, up to
// one 16-bit step, except for rays that graze an edge; any side, not only multiples of 8.
TEST(ShadowMap, DepthsMatchBruteForce) {
  const Scene scene = makeProceduralCity(2, 5);
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromElevationAzimuth(40, 25), 6);
  RayScene rays(scene, grid.origin);
  for (uint32_t side : {64u, 45u}) {
    const ShadowMap map = renderShadowMap(rays, grid, side);
    EXPECT_EQ(map.bytes(), uint64_t(side) * side * 2);
    uint64_t bad = 0, ambiguousTexels = 0, hits = 0;
    for (uint32_t y = 0; y < side; ++y)
      for (uint32_t x = 0; x < side; ++x) {
        const Vec3 from = map.toWorld({x + 0.5, y + 0.5, 0.0});
        bool ambiguous = false;
        const double t = bruteForceHit(scene, from, grid.frame.dir, ambiguous);
        const uint16_t want = std::isinf(t) ? ShadowMap::kEmpty : ShadowMap::quantize(t, grid.depthExtent);
        hits += !std::isinf(t);
        if (ambiguous) {
          ++ambiguousTexels;
          continue;
        }
        bad += std::abs(int(map.at(x, y)) - int(want)) > 1;
      }
    EXPECT_EQ(bad, 0u) << "side " << side;
    // The float map stores the depths themselves.
    const ShadowMap floats = renderShadowMap(rays, grid, side, true);
    EXPECT_EQ(floats.bytes(), uint64_t(side) * side * 4);
    uint64_t badFloat = 0;
    for (uint32_t y = 0; y < side; ++y)
      for (uint32_t x = 0; x < side; ++x) {
        bool ambiguous = false;
        const double t = bruteForceHit(scene, map.toWorld({x + 0.5, y + 0.5, 0.0}), grid.frame.dir, ambiguous);
        if (ambiguous) continue;
        badFloat += std::isinf(t) ? !std::isinf(floats.floatAt(x, y))
                                  : std::abs(double(floats.floatAt(x, y)) - t) > 1e-5 * grid.depthExtent;
      }
    EXPECT_EQ(badFloat, 0u) << "side " << side;
    EXPECT_GT(hits, uint64_t(side) * side / 2) << "the city fills most of its grid";
    EXPECT_LT(ambiguousTexels, uint64_t(side) * side / 20);
  }
}

// The map's binary answer equals an exact shadow ray from the same offset point wherever
// the exact answer does not change within two of the map's texels.
TEST(ShadowMap, BinaryLookupsAreExactAwayFromBoundaries) {
  const Scene scene = makeProceduralCity(3, 2);
  const LightFrame frame = LightFrame::fromElevationAzimuth(35, 20);
  const OrthoGrid grid = makeGrid(scene, frame, 8);
  RayScene rays(scene, grid.origin);
  const auto samples = sampleSurfaces(scene, rays, ClosedMode::Auto, frame.dir, 4000, 3);
  for (uint32_t side : {256u, 300u}) {
    const ShadowMap map = renderShadowMap(rays, grid, side);
    uint64_t compared = 0, far = 0, wrong = 0, mismatches = 0;
    for (const SurfaceSample& s : samples) {
      const Vec3 q = map.offsetPoint(s.point, s.normal, 1);
      if (rays.closedNesting(q, -frame.dir, 1e6, ClosedMode::Auto) > 0) continue;
      ++compared;
      const bool lit = exactlyLit(rays, grid, q);
      const bool got = map.filtered(s.point, s.normal, 1) > 0.5f;
      mismatches += got != lit;
      const double d = boundaryDistance(rays, grid, q, s.normal, lit, map.texelSize() / 16, grid.extent / 16);
      if (d <= 2 * map.texelSize()) continue;
      ++far;
      wrong += got != lit;
    }
    EXPECT_EQ(wrong, 0u) << "side " << side << ": " << far << " points away from boundaries";
    EXPECT_GT(far, compared / 2);
    EXPECT_GT(mismatches, 0u) << "near boundaries a map of " << side << " texels must err somewhere";
  }
}

TEST(ShadowMap, RejectsBadArguments) {
  const Scene scene = floatingBox();
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection({0, -1, 0}), 6);
  EXPECT_THROW(ShadowMap(grid, 0), InputError);
  ShadowMap map(grid, 16);
  EXPECT_THROW(map.filteredAt(grid.origin, 4), InputError);
  EXPECT_THROW(map.filteredAt(grid.origin, 11), InputError);
  std::vector<float> out;
  EXPECT_THROW(map.batch({grid.origin}, {Vec3{}, Vec3{}}, 1, out), InputError);
  // Nothing rendered: every texel is empty, so everything is lit.
  EXPECT_EQ(map.filteredAt(grid.origin, 9), 1.0f);
}

// A point on the ground at a known distance d from the box's shadow edge (along u, which
// is x for a light straight down): the estimate is the first probe radius r0 * 2^k >= d.
TEST(BoundaryDistance, KnownDistanceToAShadowEdge) {
  const Scene scene = floatingBox();
  const LightFrame frame = LightFrame::fromDirection({0, -1, 0});
  ASSERT_NEAR(std::abs(frame.u.x), 1.0, 1e-12);
  const OrthoGrid grid = makeGrid(scene, frame, 8);
  RayScene rays(scene, grid.origin);
  const double r0 = 0.01, rMax = 5;
  struct Case {
    Vec3 point;
    bool lit;
    double want;
  };
  const double inf = std::numeric_limits<double>::infinity();
  const Case cases[] = {
      {{1.3, 0.01, 0.0}, true, 0.32},    // lit, 0.3 beyond the edge at x = 1
      {{1.15, 0.01, 0.3}, true, 0.16},   // lit, 0.15 beyond it
      {{1.005, 0.01, 0.0}, true, 0.01},  // lit, within the first radius
      {{0.8, 0.01, 0.0}, false, 0.32},   // shadowed, 0.2 inside the edge
      {{0.0, 0.01, -0.55}, false, 0.64}, // shadowed, 0.45 inside the edge at z = -1
      {{6.0, 0.01, 6.0}, true, inf},     // lit, 7.07 from the shadow's corner: beyond rMax
  };
  for (const Case& c : cases) {
    ASSERT_EQ(exactlyLit(rays, grid, c.point), c.lit) << c.point.x << ", " << c.point.z;
    const double got = boundaryDistance(rays, grid, c.point, {0, 1, 0}, c.lit, r0, rMax);
    if (std::isinf(c.want)) {
      EXPECT_TRUE(std::isinf(got)) << got;
    } else {
      EXPECT_NEAR(got, c.want, 1e-12) << "point " << c.point.x << ", " << c.point.z;
    }
  }
  // Towards the light a point under the box stays shadowed until it leaves the box's top.
  EXPECT_TRUE(std::isinf(boundaryDistance(rays, grid, {0, 0.01, 0}, {0, 1, 0}, false, 0.01, 0.5)));
  // Bins in texels, (a, b] with a hair of tolerance at the edges.
  EXPECT_EQ(distanceBin(0.5, 1.0), 0);
  EXPECT_EQ(distanceBin(1.0, 1.0), 0);
  EXPECT_EQ(distanceBin(1.5, 1.0), 1);
  EXPECT_EQ(distanceBin(2.0, 1.0), 1);
  EXPECT_EQ(distanceBin(4.0, 1.0), 2);
  EXPECT_EQ(distanceBin(8.0, 1.0), 3);
  EXPECT_EQ(distanceBin(8.1, 1.0), 4);
  EXPECT_EQ(distanceBin(inf, 1.0), 4);
}

// On a sloped receiver the probes follow the receiver's plane: the estimate is the
// distance to the box's shadow edge, not to the ramp the point lies just above, which
// probes at the point's own depth would meet within a few hundredths.
TEST(BoundaryDistance, FollowsASlopedReceiver) {
  Scene scene;
  scene.name = "box over a ramp";
  appendBox(scene, {-1, 1, -1}, {1, 3, 1});
  const auto ramp = [](double x, double z) { return Vec3{x, 0.3 * x - 4, z}; };
  for (const Vec3& p : {ramp(-10, -10), ramp(10, -10), ramp(10, 10), ramp(-10, 10)}) scene.positions.push_back(p);
  for (uint32_t t : {8u, 10u, 9u, 8u, 11u, 10u}) scene.indices.push_back(t);  // facing up
  finalizeScene(scene);
  const LightFrame frame = LightFrame::fromDirection({0, -1, 0});
  const OrthoGrid grid = makeGrid(scene, frame, 8);
  RayScene rays(scene, grid.origin);
  const Vec3 n = normalize(Vec3{-0.3, 1, 0});
  const Vec3 q = ramp(1.3, 0) + n * 0.02;  // lit, about 0.294 across the light from the edge at x = 1
  ASSERT_TRUE(exactlyLit(rays, grid, q));
  EXPECT_NEAR(boundaryDistance(rays, grid, q, n, true, 0.01, 5), 0.32, 1e-12);
  // At q's own depth the ramp rises 0.3 per unit in +x and is met at about 0.07.
  EXPECT_NEAR(boundaryDistance(rays, grid, q, {}, true, 0.01, 5), 0.08, 1e-12);
}

// The exact footprint fraction over a known shadow edge: a 3x3 footprint straddling the
// edge of the box's shadow sees the lit column of texels only.
TEST(BoundaryDistance, ExactFootprintOverAnEdge) {
  const Scene scene = floatingBox();
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection({0, -1, 0}), 8);
  RayScene rays(scene, grid.origin);
  // The point on the edge x = 1 lies in texel k; the footprint's centres k - 1/2, k + 1/2
  // and k + 3/2 (in u) fall on both sides of the edge whichever way u points, so one or two
  // of the three columns are lit.
  const uint32_t side = 256;
  const double f = exactFootprintLit(rays, grid, side, {1.0, 0.01, 0.0}, 3);
  EXPECT_TRUE(std::abs(f - 1.0 / 3) < 1e-12 || std::abs(f - 2.0 / 3) < 1e-12) << f;
  // With 4 x 4 rays per texel the area average is finer than thirds but still in (0, 1).
  const double area = exactFootprintLit(rays, grid, side, {1.0, 0.01, 0.0}, 3, 4);
  EXPECT_GT(area, 0.0);
  EXPECT_LT(area, 1.0);
  // Far from the box, all lit; in the middle of its shadow, all dark.
  EXPECT_EQ(exactFootprintLit(rays, grid, side, {5, 0.01, 5}, 9, 4), 1.0);
  EXPECT_EQ(exactFootprintLit(rays, grid, side, {0, 0.01, 0}, 9, 4), 0.0);
}

// On the city, finer grids answer no worse: every method's binary mismatch rate at 1024
// is at most its rate at 256, CPVS mismatches all lie within 4 texels of a boundary, and
// the equal-bytes map has the DAG's bytes.
// Camera sampling: every point is the first surface its camera sees (nothing between the
// eye and it), with the normal of the side the camera sees; the same points for a seed
// whatever the threads; points spread over the view (not one pixel); a camera looking at
// the sky gives none.
TEST(CameraSampling, PointsAreWhatTheCamerasSee) {
  const Scene scene = makeProceduralCity(3, 5);
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromElevationAzimuth(35, 20), 8);
  RayScene rays(scene, grid.origin);
  const std::vector<Camera> cameras{defaultCamera(scene, grid.frame.dir, 16.0 / 9.0),
                                    Camera::parse("0,60,150,36,0,36,60")};
  const std::vector<SurfaceSample> a = sampleCameraViews(scene, rays, cameras, 16.0 / 9.0, 4000, 3);
  EXPECT_GT(a.size(), 3600u) << "the cameras look at the city: few rays see only sky";
  EXPECT_LE(a.size(), 4000u);
  Vec3 lo{1e300, 1e300, 1e300}, hi = -lo;
  for (size_t i = 0; i < a.size(); ++i) {
    // Dropped samples shift the cameras' turns: find the camera that sees the point.
    bool seen = false;
    for (const Camera& c : cameras) {
      const Vec3 toPoint = a[i].point - c.eye;
      const double dist = length(toPoint);
      if (dot(a[i].normal, toPoint) < 0 && !rays.occluded(c.eye, toPoint / dist, 0.0, dist * (1 - 1e-6))) seen = true;
    }
    EXPECT_TRUE(seen) << "sample " << i << " is hidden from every camera or seen from its back";
    EXPECT_NEAR(length(a[i].normal), 1.0, 1e-12);
    const Vec3& p = a[i].point;
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  EXPECT_GT(hi.x - lo.x, 20.0);
  EXPECT_GT(hi.z - lo.z, 20.0);
  std::vector<SurfaceSample> b;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    b = sampleCameraViews(scene, rays, cameras, 16.0 / 9.0, 4000, 3);
  }
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].point, b[i].point) << i;
    EXPECT_EQ(a[i].normal, b[i].normal) << i;
  }
  EXPECT_TRUE(sampleCameraViews(scene, rays, {Camera::parse("0,1000,0,0,2000,0")}, 1.0, 100, 1).empty());
  EXPECT_THROW(sampleCameraViews(scene, rays, {}, 1.0, 100, 1), InputError);
}

// With receivers declared, the CPVS for receivers everywhere is measured beside the
// declared one: more bytes, and at the declared receivers' points the same answers away
// from closed parts' surfaces.
TEST(Accuracy, ACpvsForReceiversEverywhereStandsBesideTheDeclaredOne) {
  const Scene scene = makeProceduralCity(4, 7);
  AccuracyOptions opt;
  opt.log2Resolutions = {9};
  opt.samples = 4000;
  opt.pcfSamples = 300;
  opt.minTimingSeconds = 0.002;
  opt.receivers.kind = ReceiverKind::Surfaces;
  opt.receivers.maxPcf = 9;
  const AccuracyReport rep = measureAccuracy(scene, LightFrame::fromElevationAzimuth(35, 20), opt);
  ASSERT_EQ(rep.rows.size(), size_t(kAccuracyMethods));
  const AccuracyRow& declared = rep.rows[0];
  const AccuracyRow& everywhere = rep.rows[size_t(AccuracyMethod::CpvsEverywhere)];
  ASSERT_EQ(everywhere.method, AccuracyMethod::CpvsEverywhere);
  ASSERT_FALSE(everywhere.skipped) << everywhere.note;
  EXPECT_GT(everywhere.bytes, declared.bytes);
  EXPECT_GT(everywhere.bakeSeconds, 0.0);
  // Both answer every voxel the receivers read alike; they may differ only where a query
  // point's voxel straddles a closed part's surface (each resolves it its own way), within
  // two texels of a boundary.
  EXPECT_EQ(everywhere.samples, declared.samples);
  for (int b = 2; b < kDistanceBins; ++b) EXPECT_EQ(everywhere.binMismatches[b], declared.binMismatches[b]) << "bin " << b;
  EXPECT_LE(everywhere.mismatchRate(), 1.2 * declared.mismatchRate() + 0.001);
  for (size_t w = 0; w < kAccuracyPcfWidths.size(); ++w) {
    EXPECT_EQ(everywhere.pcf[w].samples, declared.pcf[w].samples);
    EXPECT_GT(everywhere.pcf[w].nsPerQuery, 0.0);
  }
  EXPECT_NE(accuracyCsv(rep).find("cpvs_everywhere"), std::string::npos);
  EXPECT_NE(accuracyMarkdown(rep).find("| CPVS, receivers everywhere | 512 |"), std::string::npos);
}

TEST(Accuracy, MismatchFallsWithResolutionOnTheCity) {
  const Scene scene = makeProceduralCity(4, 7);
  AccuracyOptions opt;
  opt.log2Resolutions = {10, 8};
  opt.samples = 6000;
  opt.pcfSamples = 600;
  opt.minTimingSeconds = 0.005;
  const AccuracyReport rep = measureAccuracy(scene, LightFrame::fromElevationAzimuth(35, 20), opt);
  ASSERT_EQ(rep.rows.size(), 2u * kAccuracyMethods);
  EXPECT_EQ(rep.samples, 6000u);
  EXPECT_EQ(rep.pcfSamples, 600u);
  for (int m = 0; m < kAccuracyMethods; ++m) {
    const AccuracyRow& coarse = rep.rows[m];
    const AccuracyRow& fine = rep.rows[kAccuracyMethods + m];
    ASSERT_EQ(int(coarse.method), m);
    if (AccuracyMethod(m) == AccuracyMethod::CpvsEverywhere) {  // the CPVS row is that bake here
      EXPECT_TRUE(coarse.skipped);
      EXPECT_NE(coarse.note.find("receivers everywhere"), std::string::npos) << coarse.note;
      continue;
    }
    EXPECT_EQ(coarse.log2Resolution, 8);
    EXPECT_EQ(fine.log2Resolution, 10);
    EXPECT_FALSE(fine.skipped);
    EXPECT_GT(coarse.samples, 4000u);  // faces hidden where buildings stand on the slab are skipped
    EXPECT_GT(coarse.mismatches, 0u) << accuracyMethodName(AccuracyMethod(m));
    // A map of the CPVS's bytes read with the CPVS's offset is the exception: the offset
    // shrinks with the grid's voxel (4x from 256 to 1024) faster than the map's texel does
    // (its side grows with the root of the bytes), so its acne can grow.
    if (AccuracyMethod(m) != AccuracyMethod::ShadowMapEqualBytesCpvsOffset)
      EXPECT_LE(fine.mismatchRate(), coarse.mismatchRate()) << accuracyMethodName(AccuracyMethod(m));
    uint64_t binned = 0;
    for (int b = 0; b < kDistanceBins; ++b) binned += fine.binSamples[b];
    EXPECT_EQ(binned, fine.samples);
    for (const PcfAccuracy& p : fine.pcfArea) {
      EXPECT_GT(p.samples, 450u) << accuracyMethodName(AccuracyMethod(m));  // of 600: a coarse map's offset moves some points into buildings
      EXPECT_GE(p.p99AbsError, p.meanAbsError);
      EXPECT_LE(p.p99AbsError, 1.0);
    }
    EXPECT_GT(fine.nsPerQuery, 0.0);
  }
  for (const AccuracyRow* r : {&rep.rows[0], &rep.rows[kAccuracyMethods]}) {
    ASSERT_EQ(r->method, AccuracyMethod::Cpvs);
    EXPECT_EQ(r->binMismatches[3] + r->binMismatches[4], 0u) << "CPVS mismatch beyond 4 texels at R " << r->resolution();
    EXPECT_GT(r->ratioToShadowMap(), 1.0);
    EXPECT_GT(r->stageSeconds.count("render"), 0u);
    const AccuracyRow& eq = r[1];
    EXPECT_EQ(eq.side, uint64_t(std::floor(std::sqrt(double(r->bytes) / 2))));
    EXPECT_LE(eq.bytes, r->bytes);
    // The full-resolution map has the CPVS's texels and offset points: the same samples.
    const AccuracyRow& full = r[3];
    EXPECT_EQ(full.side, r->resolution());
    EXPECT_EQ(full.samples, r->samples);
    // The float map: the same texels, twice the 16-bit map's bytes, depths without
    // quantization (so no more mismatches than the 16-bit map's, but for float rounding).
    const AccuracyRow& floats = r[size_t(AccuracyMethod::FloatMapFull)];
    ASSERT_EQ(floats.method, AccuracyMethod::FloatMapFull);
    EXPECT_EQ(floats.side, r->resolution());
    EXPECT_EQ(floats.bytes, 2 * full.bytes);
    EXPECT_EQ(floats.samples, r->samples);
    EXPECT_LE(floats.mismatchRate(), full.mismatchRate() + 0.002);
  }
  // The DAG-MH of the same receivers answers every defined voxel as the CPVS: they differ
  // only where a query point's voxel straddles a closed part's surface (undefined, each
  // resolving it its own way), within two texels of a boundary.
  for (int k = 0; k < 2; ++k) {
    const AccuracyRow& cpvs = rep.rows[size_t(k) * kAccuracyMethods];
    const AccuracyRow& dagMh = rep.rows[size_t(k) * kAccuracyMethods + size_t(AccuracyMethod::DagMh)];
    ASSERT_EQ(dagMh.method, AccuracyMethod::DagMh);
    EXPECT_EQ(dagMh.samples, cpvs.samples);
    for (int b = 2; b < kDistanceBins; ++b) EXPECT_EQ(dagMh.binMismatches[b], cpvs.binMismatches[b]) << "bin " << b;
    EXPECT_LE(dagMh.mismatchRate(), 1.2 * cpvs.mismatchRate() + 0.001);
    EXPECT_GT(dagMh.bytes, 0u);
    EXPECT_GT(dagMh.bakeSeconds, 0.0);
  }
  // The area-average PCF error falls with resolution for the CPVS.
  EXPECT_LT(rep.rows[kAccuracyMethods].pcfArea[0].meanAbsError, rep.rows[0].pcfArea[0].meanAbsError);
  // A full map over the byte limit is skipped, and says so.
  opt.log2Resolutions = {8};
  opt.samples = 300;
  opt.pcfSamples = 50;
  opt.maxFullShadowMapBytes = 1000;
  const AccuracyReport small = measureAccuracy(scene, LightFrame::fromElevationAzimuth(35, 20), opt);
  EXPECT_TRUE(small.rows[3].skipped);
  EXPECT_NE(small.rows[3].note.find("skipped"), std::string::npos);
  EXPECT_TRUE(small.rows[size_t(AccuracyMethod::FloatMapFull)].skipped);
  EXPECT_NE(accuracyCsv(small).find("skipped"), std::string::npos);
  opt.log2Resolutions.clear();
  EXPECT_THROW(measureAccuracy(scene, LightFrame::fromElevationAzimuth(35, 20), opt), InputError);
}

using CliRun = testing::CommandResult;

CliRun cpvs(const std::string& args, bool withStderr = true) {
  return testing::runShell("timeout 120 '" CPVS_CLI "' " + args + (withStderr ? " 2>&1" : " 2>/dev/null"));
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Splits one CSV line, honouring double quotes.
std::vector<std::string> csvFields(const std::string& line) {
  std::vector<std::string> out(1);
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') out.back() += '"', ++i;
      else if (c == '"') quoted = false;
      else out.back() += c;
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      out.emplace_back();
    } else {
      out.back() += c;
    }
  }
  return out;
}

// Every element opened is closed, in order; returns the first problem or "".
std::string checkTags(const std::string& xml) {
  std::vector<std::string> stack;
  size_t i = 0;
  while ((i = xml.find('<', i)) != std::string::npos) {
    size_t e = xml.find('>', i);
    if (e == std::string::npos) return "unterminated tag";
    std::string tag = xml.substr(i + 1, e - i - 1);
    i = e + 1;
    if (tag.empty() || tag[0] == '?' || tag[0] == '!') continue;
    if (tag[0] == '/') {
      std::string name = tag.substr(1);
      if (stack.empty() || stack.back() != name) return "</" + name + "> closes " + (stack.empty() ? "nothing" : stack.back());
      stack.pop_back();
    } else if (tag.back() != '/') {
      stack.push_back(tag.substr(0, tag.find_first_of(" \n\t")));
    }
  }
  return stack.empty() ? "" : "<" + stack.back() + "> never closed";
}

class AccuracyCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("cpvs_accuracy_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(AccuracyCli, WritesTablesCsvAndPlot) {
  const fs::path out = dir_ / "out" / "nested";
  CliRun r = cpvs("accuracy city:3 --sun-elevation 35 --sun-azimuth 20 --resolutions 256,512 --samples 2000 "
                  "--pcf-samples 300 --timing-seconds 0.005 --out " + out.string(), false);
  ASSERT_EQ(r.status, 0) << r.out;
  // stdout: the Markdown table, one row per method and resolution.
  EXPECT_EQ(r.out.rfind("| method | R |", 0), 0u) << r.out;
  EXPECT_NE(r.out.find("| CPVS | 512 |"), std::string::npos) << r.out;

  const std::string md = slurp(out / "accuracy.md");
  EXPECT_NE(md.find("| shadow map, full resolution | 256 |"), std::string::npos);
  EXPECT_NE(md.find("## How it is measured"), std::string::npos);

  std::istringstream csv(slurp(out / "accuracy.csv"));
  std::string line;
  ASSERT_TRUE(std::getline(csv, line));
  const auto header = csvFields(line);
  EXPECT_EQ(header[0], "scene");
  EXPECT_EQ(header.back(), "note");
  size_t rows = 0;
  int methodCol = -1, rateCol = -1, skippedCol = -1;
  for (size_t i = 0; i < header.size(); ++i) {
    if (header[i] == "method") methodCol = int(i);
    if (header[i] == "mismatch_rate") rateCol = int(i);
    if (header[i] == "skipped") skippedCol = int(i);
  }
  ASSERT_GE(methodCol, 0);
  ASSERT_GE(rateCol, 0);
  ASSERT_GE(skippedCol, 0);
  while (std::getline(csv, line)) {
    const auto f = csvFields(line);
    ASSERT_EQ(f.size(), header.size()) << line;
    ++rows;
    if (f[skippedCol] == "1") {  // the CPVS for receivers everywhere is the CPVS row's bake here
      EXPECT_EQ(f[methodCol], "cpvs_everywhere") << line;
      EXPECT_EQ(f[rateCol], "") << line;
      continue;
    }
    const double rate = std::stod(f[rateCol]);
    EXPECT_GE(rate, 0.0);
    EXPECT_LE(rate, 1.0);
  }
  EXPECT_EQ(rows, 2u * kAccuracyMethods);

  const std::string svg = slurp(out / "accuracy.svg");
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  EXPECT_EQ(checkTags(svg), "");
  EXPECT_NE(svg.find("<polyline"), std::string::npos);
  EXPECT_NE(svg.find("shadow map, equal bytes"), std::string::npos);
}

TEST_F(AccuracyCli, SamplesWhatTheCamerasSee) {
  const fs::path out = dir_ / "cameras";
  CliRun r = cpvs("accuracy city:3 --sun-elevation 35 --resolutions 256 --samples 500 --pcf-samples 50 "
                  "--timing-seconds 0.001 --camera default --camera 0,60,150,36,0,36 -q --out " + out.string());
  ASSERT_EQ(r.status, 0) << r.out;
  const std::string md = slurp(out / "accuracy.md");
  EXPECT_NE(md.find("seen by 2 cameras: at ("), std::string::npos) << md.substr(0, 600);
  EXPECT_NE(md.find("looking at (36, 0, 36), 40°"), std::string::npos) << md.substr(0, 600);
  EXPECT_NE(md.find("rays through uniformly random points of the cameras' images"), std::string::npos);
}

// The receiver declaration reaches the bake and the sampling: a bake for surfaces is
// measured on its declared receivers and says so.
TEST_F(AccuracyCli, MeasuresABakeForItsReceivers) {
  const fs::path out = dir_ / "receivers";
  CliRun r = cpvs("accuracy city:3 --sun-elevation 35 --resolutions 256 --samples 2000 --pcf-samples 50 "
                  "--timing-seconds 0.001 --receivers surfaces --receiver-pcf 3 -q --out " + out.string());
  ASSERT_EQ(r.status, 0) << r.out;
  const std::string md = slurp(out / "accuracy.md");
  EXPECT_NE(md.find("over the declared receivers; the CPVS is baked for receivers 'surfaces' with PCF up to 3"),
            std::string::npos)
      << md.substr(0, 600);
  EXPECT_NE(slurp(out / "accuracy.csv").find(",receivers_s,"), std::string::npos);
}

TEST_F(AccuracyCli, RefusesBadInputWithExitStatus2) {
  const std::string base = "accuracy city:2 --sun-elevation 35 --samples 200 --out " + (dir_ / "o").string();
  struct Bad {
    std::string args, message;
  };
  std::ofstream(dir_ / "file") << "x";
  const Bad cases[] = {
      {base + " --resolutions 1K,3K", "3K"},
      {base + " --resolutions 256,,512", "--resolutions"},
      {base + " --resolutions 4", "outside"},
      {"accuracy city:2 --sun-elevation 35 --samples 99 --out " + (dir_ / "o").string(), "--samples"},
      {"accuracy city:2 --sun-elevation 35 --out " + (dir_ / "file" / "sub").string(), "--out"},
      {"accuracy city:2 --out " + (dir_ / "o").string(), "--sun-dir"},
      {base + " --sun-dir 0,-1,0", "not both"},
      {base + " --tile-size 100", "--tile-size"},
      {"accuracy no-such-scene.obj --sun-elevation 35 --out " + (dir_ / "o").string(), "no-such-scene.obj"},
      {base + " --camera 1,2,3", "EX,EY,EZ,TX,TY,TZ"},
      {base + " --camera 0,1000,0,0,2000,0", "the cameras see no surface"},  // looking up, at the sky
      {base + " --receivers volume", "needs a volume"},
  };
  for (const Bad& b : cases) {
    CliRun r = cpvs(b.args);
    EXPECT_EQ(r.status, 2) << b.args << "\n" << r.out;
    EXPECT_NE(r.out.find(b.message), std::string::npos) << b.args << "\n" << r.out;
  }
}

}  // namespace
}  // namespace cpvs
