// Hard cases that must stay numerically stable. Each bakes a small grid and checks it
// against exact ray-traced visibility (no mismatch away from shadow boundaries), and,
// where the case is a transformation of an easy one, that the answers do not change
// beyond the voxels next to a boundary.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "scene_testing.h"
#include "cpvs/scene/boxes.h"
#include "cpvs/base/error.h"
#include "cpvs/bake/bake.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/eval/verify.h"
#include "cpvs/raytrace/visibility.h"
#include "cpvs/scene/source.h"
#include "dag_testing.h"

namespace cpvs {
namespace {

using testing::bakeTileWith;
using testing::bakeWith;

struct Baked {
  CpvsArtifact art;
  VerifyResult verify;
};

/// Bakes `scene` at 2^log2R with `dir`, small tiles, and verifies it at `samples` points.
Baked bakeAndVerify(const Scene& scene, const Vec3& dir, int log2R, uint64_t samples = 8000,
                    ClosedMode closed = ClosedMode::Auto) {
  Baked b;
  b.art.grid = makeGrid(scene, LightFrame::fromDirection(dir), log2R);
  b.art.options.closed = closed;
  b.art.options.log2TileSize = std::min(log2R, 6);
  RayScene rays(scene, b.art.grid.origin);
  b.art.dag = bakeWith(scene, b.art.grid, b.art.options);
  b.art.sceneHash = sceneHash(scene);
  ShadowQuery q(b.art.grid, PackedDag(b.art.dag));
  const TopTree psv = verificationTree(scene, PsvLight::sun(b.art.grid.frame.dir));
  b.verify = verifyArtifact(q, b.art.options.closed, scene, rays, samples, 7, {&psv});
  return b;
}

#define EXPECT_EXACT_AWAY_FROM_BOUNDARIES(b, what)                                                          \
  do {                                                                                                        \
    EXPECT_GT((b).verify.samples, 1000u) << what;                                                             \
    EXPECT_EQ((b).verify.mismatchElsewhere, 0u) << what;                                                      \
    EXPECT_EQ((b).verify.oraclesCompared, (b).verify.samples) << what;                                        \
    EXPECT_EQ((b).verify.oraclesDisagreeElsewhere, 0u) << what << ": Embree and the TOP tree differ";          \
    EXPECT_LT((b).verify.fractionNearBoundary(), 0.05) << what;                                               \
  } while (0)

Scene translated(Scene s, const Vec3& t) {
  for (Vec3& p : s.positions) p = p + t;
  return s;
}

// --- sun directions ---------------------------------------------------------------------

// Axis-aligned suns from all six sides, and suns 1e-7 radians off an axis: the frame is
// built without a branch on the direction, so none of them is a special case.
TEST(HardCases, AxisAlignedAndNearlyAxisAlignedSuns) {
  Scene city = openScene("city:3:2");
  const double e = 1e-7;
  for (Vec3 d : {Vec3{1, 0, 0}, Vec3{-1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, -1, 0}, Vec3{0, 0, 1}, Vec3{0, 0, -1},
                 Vec3{e, -1, 0}, Vec3{0, -1, e}, Vec3{-e, -1, e}, Vec3{1, e, 0}, Vec3{0, e, -1}}) {
    LightFrame f = LightFrame::fromDirection(d);
    EXPECT_NEAR(dot(f.u, f.v), 0, 1e-15);
    EXPECT_NEAR(dot(f.u, f.dir), 0, 1e-15);
    EXPECT_NEAR(length(cross(f.u, f.v) - f.dir), 0, 1e-12) << "right-handed";
    Baked b = bakeAndVerify(city, d, 7);
    EXPECT_EXACT_AWAY_FROM_BOUNDARIES(b, "sun " << d.x << "," << d.y << "," << d.z);
  }
}

// A light vector is only a direction: components near the ends of the double range
// give the same frame as ordinary ones instead of overflowing to "not finite" or
// underflowing to the zero vector; the zero vector and NaN are refused by name.
TEST(HardCases, LightVectorsOfAnyMagnitude) {
  const LightFrame want = LightFrame::fromDirection({0.3, -1, 0.2});
  for (double scale : {1e300, 1e-300, 4.9e-322}) {
    const LightFrame f = LightFrame::fromDirection(Vec3{0.3, -1, 0.2} * scale);
    EXPECT_NEAR(length(f.dir - want.dir), 0, 1e-2) << "scale " << scale;  // subnormals keep few digits
    if (scale >= 1e-300) {
      EXPECT_NEAR(length(f.dir - want.dir), 0, 1e-15) << "scale " << scale;
    }
    EXPECT_NEAR(length(f.dir), 1, 1e-15);
  }
  const LightFrame huge = LightFrame::fromDirection({1e308, -1e308, 1e308});
  EXPECT_NEAR(huge.dir.y, -1 / std::sqrt(3.0), 1e-15);
  try {
    LightFrame::fromDirection({0, 0, 0});
    ADD_FAILURE() << "the zero vector was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("zero vector"), std::string::npos) << e.what();
  }
  EXPECT_THROW(LightFrame::fromDirection({std::nan(""), -1, 0}), InputError);
}

// Grazing suns stretch the grid's depth range across the whole city.
TEST(HardCases, GrazingSuns) {
  Scene city = openScene("city:3:2");
  for (double elevation : {0.1, 1.0}) {
    LightFrame f = LightFrame::fromElevationAzimuth(elevation, 30);
    Baked b = bakeAndVerify(city, f.dir, 8);
    EXPECT_EXACT_AWAY_FROM_BOUNDARIES(b, "elevation " << elevation);
  }
  EXPECT_THROW(LightFrame::fromElevationAzimuth(-0.1, 0), InputError);
  // Given as a vector, a light from below is valid.
  Baked below = bakeAndVerify(city, Vec3{0.2, 1, 0.1}, 7);
  EXPECT_EXACT_AWAY_FROM_BOUNDARIES(below, "light from below");
}

// --- far from the origin, tiny and huge scenes ---------------------------------------------

// The city's coordinates are integers: translated by up to 1e7 they stay exactly
// representable in float (below 2^24), so any difference is the pipeline's own. The grid
// is fitted to the bounds, so the translated bake must give the same DAG.
TEST(HardCases, FarFromTheOrigin) {
  Scene city = openScene("city:3:2");
  const Vec3 sun{0.3, -1, 0.2};
  Baked here = bakeAndVerify(city, sun, 8);
  for (double t : {1e5, 1e6, 1e7}) {
    Baked there = bakeAndVerify(translated(city, {t, -t / 2, t}), sun, 8);
    EXPECT_EXACT_AWAY_FROM_BOUNDARIES(there, "translated by " << t);
    EXPECT_EQ(there.art.dag.bytes(), here.art.dag.bytes()) << "translated by " << t;
    // Same voxels: compare lookups at random voxels.
    std::mt19937_64 rng(1);
    uint64_t differ = 0, R = here.art.grid.resolution();
    for (int i = 0; i < 100000; ++i) {
      uint64_t x = rng() % R, y = rng() % R, z = rng() % R;
      differ += dagVoxelShadowed(here.art.dag, x, y, z) != dagVoxelShadowed(there.art.dag, x, y, z);
    }
    EXPECT_EQ(differ, 0u) << "translated by " << t;
  }
}

// Mirrored in x, scene and light together: a mirror image of the same shadows. The grid
// of the mirror image is not the mirror of the grid (the light frame is built from the
// direction alone), so answers are compared at corresponding surface points: they may
// differ only where one of the two lookups is within a voxel of a shadow boundary.
TEST(HardCases, MirroredSceneAndLight) {
  Scene city = openScene("city:3:2");
  Scene mirror = city;
  for (Vec3& p : mirror.positions) p.x = -p.x;
  for (size_t t = 0; t < mirror.triangleCount(); ++t) std::swap(mirror.indices[3 * t + 1], mirror.indices[3 * t + 2]);
  SceneStats stats = finalizeScene(mirror);
  EXPECT_EQ(stats.closedTriangles, city.triangleCount()) << "mirrored with its winding flipped, still closed";
  const Vec3 sun{0.3, -1, 0.2}, mirroredSun{-0.3, -1, 0.2};
  Baked a = bakeAndVerify(city, sun, 8), b = bakeAndVerify(mirror, mirroredSun, 8);
  EXPECT_EXACT_AWAY_FROM_BOUNDARIES(a, "original");
  EXPECT_EXACT_AWAY_FROM_BOUNDARIES(b, "mirrored");
  RayScene rays(city, a.art.grid.origin);
  ShadowQuery qa(a.art.grid, PackedDag(a.art.dag)), qb(b.art.grid, PackedDag(b.art.dag));
  auto samples = sampleSurfaces(city, rays, ClosedMode::Auto, a.art.grid.frame.dir, 20000, 9);
  uint64_t differ = 0;
  for (const auto& s : samples) {
    Vec3 mp{-s.point.x, s.point.y, s.point.z}, mn{-s.normal.x, s.normal.y, s.normal.z};
    differ += qa.visibility(s.point, s.normal) != qb.visibility(mp, mn);
  }
  EXPECT_LT(double(differ) / double(samples.size()), 0.03) << differ << " of " << samples.size();
}

Scene scaled(Scene s, double k) {
  for (Vec3& p : s.positions) p = p * k;
  return s;
}

TEST(HardCases, TinyAndHugeScenes) {
  Scene city = openScene("city:3:2");
  const Vec3 sun{0.3, -1, 0.2};
  Baked tiny = bakeAndVerify(scaled(city, 1e-3 / 100), sun, 8);  // about 1e-3 across
  EXPECT_EXACT_AWAY_FROM_BOUNDARIES(tiny, "1e-3 units across");
  // 1e5 units across, with a detail far below one voxel: a 0.01-unit box on a roof.
  Scene huge = scaled(city, 1e5 / 100);
  appendBox(huge, {50000, 0, 50000}, {50000.01, 30000.01, 50000.01});
  finalizeScene(huge);
  Baked b = bakeAndVerify(huge, sun, 8);
  EXPECT_EXACT_AWAY_FROM_BOUNDARIES(b, "1e5 across with a sub-voxel needle");
  for (const Vec3& p : {Vec3{1, 2, 3}, Vec3{5e4, 3e4, 5e4}})
    EXPECT_TRUE(std::isfinite(b.art.grid.voxelFromWorld(p).x) && std::isfinite(b.art.grid.voxelFromWorld(p).z));
}

// --- awkward geometry ------------------------------------------------------------------------


TEST(HardCases, ThinCoplanarOverlappingDuplicatedAndDegenerateTriangles) {
  Scene s;
  appendBox(s, {0, 0, 0}, {100, 2, 100});         // ground
  appendBox(s, {10, 2, 10}, {10.05, 40, 60});     // a wall far thinner than a voxel
  appendBox(s, {30, 2, 30}, {50, 20, 50});        // two boxes overlapping each other
  appendBox(s, {40, 2, 40}, {60, 25, 60});
  size_t before = s.indices.size();
  for (size_t i = before - 36; i < before; ++i) s.indices.push_back(s.indices[i]);  // a duplicated box
  // A coplanar open quad lying on the ground's top, and zero-area triangles.
  uint32_t q = uint32_t(s.positions.size());
  for (Vec3 p : {Vec3{60, 2, 60}, Vec3{90, 2, 60}, Vec3{90, 2, 90}, Vec3{60, 2, 90}}) s.positions.push_back(p);
  for (uint32_t i : {0u, 2u, 1u, 0u, 3u, 2u, 0u, 0u, 1u, 1u, 1u, 1u}) s.indices.push_back(q + i);
  SceneStats stats = finalizeScene(s);
  EXPECT_EQ(stats.degenerateDropped, 2u);
  for (Vec3 sun : {Vec3{0.3, -1, 0.2}, Vec3{-0.5, -0.4, 0.1}}) {
    Baked b = bakeAndVerify(s, sun, 8);
    EXPECT_EXACT_AWAY_FROM_BOUNDARIES(b, "sun " << sun.x << "," << sun.y << "," << sun.z);
  }
}

// Two closed boxes that intersect (a self-intersecting closed mesh when taken together):
// the exact exit depth counts faces, so the interior of both stays undefined and the
// voxels behind them stay shadowed; the approximate exit stops at the first back face,
// which is still behind the enter depth, so both must verify.
TEST(HardCases, SelfIntersectingClosedMeshes) {
  Scene s;
  appendBox(s, {0, 0, 0}, {100, 2, 100});
  appendBox(s, {20, 2, 20}, {60, 30, 60});
  appendBox(s, {40, 10, 40}, {80, 50, 80});
  finalizeScene(s);
  for (ExitMode exit : {ExitMode::Exact, ExitMode::Approx}) {
    CpvsArtifact art;
    art.grid = makeGrid(s, LightFrame::fromDirection({0.3, -1, 0.2}), 8);
    art.options.exit = exit;
    art.options.log2TileSize = 6;
    RayScene rays(s, art.grid.origin);
    art.dag = bakeWith(s, art.grid, art.options);
    ShadowQuery q(art.grid, PackedDag(art.dag));
    const TopTree psv = verificationTree(s, PsvLight::sun(art.grid.frame.dir));
    VerifyResult r = verifyArtifact(q, art.options.closed, s, rays, 8000, 3, {&psv});
    EXPECT_EQ(r.mismatchElsewhere, 0u) << "exit " << int(exit);
    EXPECT_EQ(r.oraclesDisagreeElsewhere, 0u) << "exit " << int(exit);
  }
}

// Open meshes forced closed (--closed on) must degrade gracefully: no crash, and rays
// that never leave the "interior" keep their column defined.
TEST(HardCases, OpenMeshesForcedClosed) {
  Scene s;
  appendBox(s, {0, 0, 0}, {100, 2, 100});
  uint32_t q = uint32_t(s.positions.size());
  for (Vec3 p : {Vec3{20, 20, 20}, Vec3{80, 20, 20}, Vec3{80, 20, 80}, Vec3{20, 20, 80}}) s.positions.push_back(p);
  for (uint32_t i : {0u, 2u, 1u, 0u, 3u, 2u}) s.indices.push_back(q + i);  // a floating open roof
  finalizeScene(s);
  Baked b = bakeAndVerify(s, {0.3, -1, 0.2}, 8, 8000, ClosedMode::On);
  EXPECT_GT(b.verify.samples, 1000u);
  EXPECT_EQ(b.verify.mismatchElsewhere, 0u);
}

// --- seams and addressing ------------------------------------------------------------------

// Texels on tile borders, at several tile sizes, give the same voxels as an untiled bake.
TEST(HardCases, TileSeams) {
  Scene city = openScene("city:3:2");
  OrthoGrid grid = makeGrid(city, LightFrame::fromDirection({0.3, -1, 0.2}), 8);
  BakeOptions whole;
  whole.log2TileSize = 8;
  Dag reference = bakeWith(city, grid, whole);
  for (int log2T : {3, 4, 5, 7}) {
    BakeOptions tiled = whole;
    tiled.log2TileSize = log2T;
    Dag dag = bakeWith(city, grid, tiled);
    const uint64_t T = uint64_t(1) << log2T, R = grid.resolution();
    uint64_t differ = 0;
    for (uint64_t seam = T; seam < R; seam += T)
      for (uint64_t a : {seam - 1, seam})
        for (uint64_t b = 0; b < R; b += 3)
          for (uint64_t z = 0; z < R; z += 5) {
            differ += dagVoxelShadowed(dag, a, b, z) != dagVoxelShadowed(reference, a, b, z);
            differ += dagVoxelShadowed(dag, b, a, z) != dagVoxelShadowed(reference, b, a, z);
          }
    EXPECT_EQ(differ, 0u) << "tile " << T;
    EXPECT_EQ(dag.bytes(), reference.bytes()) << "tile " << T;
  }
}

// Index math at R = 2^18 and 2^20: voxel coordinates round-trip through world space
// exactly enough, root keys hold every block position, and one tile of a 2^18 grid bakes.
TEST(HardCases, AddressingAtTwoToThe18And20) {
  Scene city = openScene("city:3:2");
  for (int log2R : {18, 20}) {
    OrthoGrid g = makeGrid(city, LightFrame::fromDirection({0.3, -1, 0.2}), log2R);
    const double R = double(g.resolution());
    for (Vec3 v : {Vec3{0.5, 0.5, 0.5}, Vec3{R - 0.5, R - 0.5, R - 0.5}, Vec3{R / 3 + 0.25, R / 7 + 0.5, R - 1.5}}) {
      Vec3 back = g.voxelFromWorld(g.worldFromVoxel(v));
      EXPECT_NEAR(back.x, v.x, 1e-3);
      EXPECT_NEAR(back.y, v.y, 1e-3);
      EXPECT_NEAR(back.z, v.z, 1e-3);
    }
    uint64_t last = (uint64_t(1) << (log2R - 3)) - 1;  // the largest block index of 8^3 roots
    uint64_t key = rootKey(last, last - 1, last - 2);
    EXPECT_EQ(rootKeyX(key), last);
    EXPECT_EQ(rootKeyY(key), last - 1);
    EXPECT_EQ(rootKeyZ(key), last - 2);
  }
  // One 512-texel tile column of a 2^18 grid, in the middle of the city, against shadow
  // rays from the centres of a few of its voxels.
  OrthoGrid g = makeGrid(city, LightFrame::fromDirection({0.3, -1, 0.2}), 18);
  RayScene rays(city, g.origin);
  BakeOptions opt;
  opt.log2TileSize = 9;
  const uint64_t tile = (uint64_t(1) << 9) / 2;  // tile index in the middle
  Dag sub = bakeTileWith(city, g, tile, tile, opt);
  EXPECT_EQ(sub.roots.size(), uint64_t(1) << 9);
  EXPECT_GT(sub.nodeCount(), 0u);
  // Voxels of the tile whose exact visibility is the same at their centre and at every
  // point one voxel away (no shadow boundary near), outside closed solids (undefined
  // there), must hold that value.
  const double len = shadowRayLength(g);
  std::mt19937_64 rng(11);
  std::uniform_int_distribution<uint64_t> inTile(0, 511), anyZ(0, g.resolution() - 1);
  int lit = 0, shadowed = 0;
  for (int i = 0; i < 3000 && (lit < 40 || shadowed < 40); ++i) {
    const uint64_t x = tile * 512 + inTile(rng), y = tile * 512 + inTile(rng), z = anyZ(rng);
    const Vec3 centre{double(x) + 0.5, double(y) + 0.5, double(z) + 0.5};
    const Vec3 p = g.worldFromVoxel(centre);
    if (rays.closedNesting(p, -g.frame.dir, len, ClosedMode::Auto) > 0) continue;
    const bool exact = exactlyLit(rays, g, p);
    bool clear = true;
    for (int n = 0; n < 27 && clear; ++n)
      clear = exactlyLit(rays, g, g.worldFromVoxel(centre + Vec3{n % 3 - 1.0, n / 3 % 3 - 1.0, n / 9 - 1.0})) == exact;
    if (!clear) continue;
    const std::optional<bool> baked = testing::subDagVoxelShadowed(sub, x, y, z);
    ASSERT_TRUE(baked.has_value());
    EXPECT_EQ(!*baked, exact) << "voxel " << x << ", " << y << ", " << z;
    (exact ? lit : shadowed) += 1;
  }
  EXPECT_GE(lit, 40);
  EXPECT_GE(shadowed, 40);
}

}  // namespace
}  // namespace cpvs
