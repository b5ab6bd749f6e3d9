// The LightGrid mapping of a directional light, against the geometry it stands for: the
// light frame's axes, the grid corner and extents, written out here by hand once.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "cpvs/base/error.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/scene/scene.h"

namespace cpvs {
namespace {

OrthoGrid sampleGrid(int log2R = 6) {
  OrthoGrid g;
  g.frame = LightFrame::fromDirection({0.3, -1, 0.2});
  g.log2Resolution = log2R;
  g.origin = {1e5, -3, 7};  // far from the world origin
  g.u0 = -4;
  g.v0 = -5;
  g.d0 = -6;
  g.extent = 10;
  g.depthExtent = 12;
  return g;
}

// Light coordinates (relative to the origin) of a world point, by the definition.
Vec3 light(const OrthoGrid& g, const Vec3& w) {
  const Vec3 p = w - g.origin;
  return {dot(p, g.frame.u), dot(p, g.frame.v), dot(p, g.frame.dir)};
}

TEST(OrthoGrid, VoxelsAreTheLightFrameScaledToTheGrid) {
  const OrthoGrid g = sampleGrid();
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> any(-20, 20);
  for (int i = 0; i < 200; ++i) {
    const Vec3 w = g.origin + Vec3{any(rng), any(rng), any(rng)};
    const Vec3 v = g.voxelFromWorld(w), l = light(g, w);
    EXPECT_NEAR(v.x, (l.x - g.u0) / g.extent * 64, 1e-9);
    EXPECT_NEAR(v.y, (l.y - g.v0) / g.extent * 64, 1e-9);
    EXPECT_NEAR(v.z, (l.z - g.d0) / g.depthExtent * 64, 1e-9);
    const Vec3 back = g.worldFromVoxel(v);
    EXPECT_NEAR(length(back - w), 0, 1e-9);
    EXPECT_NEAR(g.depthOf(w), l.z - g.d0, 1e-9);
  }
}

TEST(OrthoGrid, TexelRaysPassThroughTexelCentresAlongTheLight) {
  const OrthoGrid g = sampleGrid();
  const Vec3 local{1e5, 0, 0};
  for (uint64_t x : {0u, 17u, 63u})
    for (uint64_t y : {0u, 40u, 63u}) {
      const TexelRay r = g.texelRay(x, y, local);
      EXPECT_EQ(r.dir, g.frame.dir);
      const Vec3 start = g.voxelFromWorld(r.origin + local);
      EXPECT_NEAR(start.x, double(x) + 0.5, 1e-9);
      EXPECT_NEAR(start.y, double(y) + 0.5, 1e-9);
      EXPECT_NEAR(start.z, 0, 1e-9);  // the near plane
      const Vec3 end = g.voxelFromWorld(r.origin + local + r.dir * r.tMax);
      EXPECT_GT(end.z, 64.0);  // a hair beyond the far end
      EXPECT_LT(end.z, 64.1);
      // Depth along the ray and slices agree with the voxel z of the point reached.
      for (double t : {0.01, 3.3, 11.9}) {
        const double z = g.voxelFromWorld(r.origin + local + r.dir * t).z;
        EXPECT_EQ(g.sliceOfDepth(t), uint32_t(std::floor(z + 1e-12)));
      }
    }
  EXPECT_EQ(g.sliceOfDepth(-1), 0u);
  EXPECT_EQ(g.sliceOfDepth(std::nan("")), 0u);
  EXPECT_EQ(g.sliceOfDepth(1e9), 64u);
}

TEST(OrthoGrid, AnotherSideCutsTheSameVolume) {
  const OrthoGrid g = sampleGrid();
  const OrthoGrid map = g.withSide(100);
  EXPECT_EQ(map.side(), 100u);
  EXPECT_EQ(map.resolution(), g.resolution());
  const Vec3 w = g.origin + Vec3{1, 2, 3};
  const Vec3 a = g.voxelFromWorld(w), b = map.voxelFromWorld(w);
  EXPECT_NEAR(b.x, a.x * 100 / 64, 1e-9);
  EXPECT_NEAR(b.z, a.z * 100 / 64, 1e-9);
  EXPECT_NEAR(map.texelSize() * 100, g.extent, 1e-12);
  EXPECT_THROW(g.withSide(0), InputError);
  EXPECT_THROW(g.withSide((uint64_t(1) << 20) + 1), InputError);
}

TEST(OrthoGrid, NormalOffsetMovesTheLargestVoxelComponentByTheGivenVoxels) {
  const OrthoGrid g = sampleGrid();
  const Vec3 w = g.origin + Vec3{1, 2, 3};
  for (const Vec3& n : {Vec3{0, 1, 0}, Vec3{0.2, 0.3, -0.9}, Vec3{1e-300, 0, 0}}) {
    const Vec3 d = g.offsetVoxel(w, n, 2.5) - g.voxelFromWorld(w);
    // At least the voxels asked for, at most 1/256 more (the reciprocal is rounded up).
    const double moved = std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)});
    EXPECT_GE(moved, 2.5 - 1e-9);
    EXPECT_LE(moved, 2.5 * (1 + 1.0 / 256) + 1e-9);
    EXPECT_GT(dot(g.worldFromVoxel(g.offsetVoxel(w, n, 2.5)) - w, n), 0);  // towards the normal
  }
  EXPECT_EQ(g.offsetVoxel(w, {}, 2.5), g.voxelFromWorld(w));
  EXPECT_EQ(g.offsetVoxel(w, {std::nan(""), 0, 0}, 2.5), g.voxelFromWorld(w));
}

// On a grid whose slices are 2^s texels deep the offset counts x and y in units of 2^s
// texels: the largest such component moves the voxels asked for, so a normal across the
// light moves 2^s times further across, and one along it as many slices as on a cubic grid.
TEST(OrthoGrid, FewerDepthSlicesCountTheOffsetAcrossInTexelsPerSlice) {
  OrthoGrid g = sampleGrid(8);
  g.depthSlices = 64;  // slices 4 texels deep
  EXPECT_EQ(g.depthShift(), 2);
  checkGrid(g, "test");
  const Vec3 w = g.origin + Vec3{1, 2, 3};
  for (const Vec3& n : {g.frame.u, g.frame.v * -1.0, g.frame.dir * -1.0, Vec3{0.2, 0.3, -0.9}, Vec3{0.9, 0.1, 0.3}}) {
    const Vec3 d = g.offsetVoxel(w, n, 2.5) - g.voxelFromWorld(w);
    const double moved = std::max({std::abs(d.x) / 4, std::abs(d.y) / 4, std::abs(d.z)});
    EXPECT_GE(moved, 2.5 - 1e-9);
    EXPECT_LE(moved, 2.5 * (1 + 1.0 / 256) + 1e-9);
    EXPECT_GT(dot(g.worldFromVoxel(g.offsetVoxel(w, n, 2.5)) - w, n), 0);
  }
  EXPECT_NEAR(std::abs((g.offsetVoxel(w, g.frame.u, 2.5) - g.voxelFromWorld(w)).x), 10, 0.1);
  EXPECT_NEAR(std::abs((g.offsetVoxel(w, g.frame.dir, 2.5) - g.voxelFromWorld(w)).z), 2.5, 0.01);
  // The scene's depth is the first quarter; a coarser count keeps slices 4 texels deep.
  EXPECT_EQ(g.sceneDepthExtent(), g.depthExtent / 4);
  EXPECT_EQ(g.withResolution(6).depthSlices, 16u);
  EXPECT_EQ(g.withResolution(6).depthShift(), 2);
  EXPECT_EQ(g.withResolution(6).sceneDepthExtent(), g.sceneDepthExtent());
  EXPECT_EQ(g.withResolution(1).depthSlices, 1u);  // down to one slice
  // A cubic grid, and the same volume at another side (a shadow map's), offset as before.
  EXPECT_EQ(g.withSide(100).depthShift(), 0);
  g.depthSlices = 0;
  EXPECT_NEAR(std::abs((g.offsetVoxel(w, g.frame.u, 2.5) - g.voxelFromWorld(w)).x), 2.5, 0.01);
  EXPECT_EQ(g.sceneDepthExtent(), g.depthExtent);
  EXPECT_EQ(g.withResolution(6).depthSlices, 0u);
  // Depth slices that are no power of two below the resolution are refused.
  for (uint32_t bad : {3u, 256u, 512u}) {
    g.depthSlices = bad;
    EXPECT_THROW(checkGrid(g, "test"), InputError) << bad;
  }
}

// The offset's scale against a plain division, over many magnitudes and every table
// entry: never below voxels / m, never more than 1/256 above it; 0 outside its range.
TEST(LookupMapping, NormalOffsetScaleBoundsTheQuotient) {
  uint64_t state = 12345;
  for (int i = 0; i < 100000; ++i) {
    state = state * 6364136223846793005u + 1442695040888963407u;
    const double m = std::ldexp(1.0 + double(state >> 11) * 0x1p-53, int(state % 200) - 100);
    for (double voxels : {1.5, 2.5, 5.5}) {
      const double s = normalOffsetScale(m, voxels), q = voxels / m;
      ASSERT_GE(s, q * (1 - 1e-15)) << m;
      ASSERT_LE(s, q * (1 + 1.0 / 256) * (1 + 1e-15)) << m;
    }
  }
  EXPECT_EQ(normalOffsetScale(0x1p-1001, 1.5), 0);
  EXPECT_EQ(normalOffsetScale(0x1p1000, 1.5), 0);
  EXPECT_EQ(normalOffsetScale(std::nan(""), 1.5), 0);
  EXPECT_EQ(normalOffsetScale(1.0, 1.5), 1.5);
  EXPECT_EQ(normalOffsetScale(0.5, 1.5), 3.0);
}

TEST(OrthoGrid, ChecksWhatFilesAndMessagesCarry) {
  EXPECT_NO_THROW(checkGrid(sampleGrid(), "g"));
  auto bad = [](auto change) {
    OrthoGrid g = sampleGrid();
    change(g);
    try {
      checkGrid(g, "grid.bin");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(bad([](OrthoGrid& g) { g.log2Resolution = 21; }).find("grid.bin: resolution"), std::string::npos);
  EXPECT_NE(bad([](OrthoGrid& g) { g.extent = 0; }).find("not positive"), std::string::npos);
  EXPECT_NE(bad([](OrthoGrid& g) { g.d0 = INFINITY; }).find("non-finite"), std::string::npos);
  EXPECT_NE(bad([](OrthoGrid& g) { g.frame.dir = g.frame.dir * (1 + 1e-8); }).find("unit vector"), std::string::npos);
}

TEST(OrthoGrid, FitsTheSceneWithAMargin) {
  Scene s;
  s.positions = {{0, 0, 0}, {10, 0, 0}, {0, 5, 3}};
  s.indices = {0, 1, 2};
  const OrthoGrid g = makeGrid(s, LightFrame::fromDirection({0.1, -1, 0.3}), 8);
  for (const Vec3& p : s.positions) {
    const Vec3 v = g.voxelFromWorld(p);
    for (double c : {v.x, v.y, v.z}) {
      EXPECT_GT(c, 0);
      EXPECT_LT(c, 256);
    }
  }
  EXPECT_THROW(makeGrid(s, LightFrame::fromDirection({0, -1, 0}), 21), InputError);
  EXPECT_THROW(makeGrid(Scene{}, LightFrame::fromDirection({0, -1, 0}), 8), InputError);
}

}  // namespace

// -0 and +0 name one direction; a grid is stored where a zero's sign does not survive
// (SQLite), so no frame or grid holds a negative zero, and the farm bakes the local bytes.
TEST(LightFrame, NoNegativeZerosAndMinusZeroIsZero) {
  auto bits = [](const Vec3& v) {
    return std::vector<bool>{std::signbit(v.x), std::signbit(v.y), std::signbit(v.z)};
  };
  for (const Vec3& d : {Vec3{0.7, -1, -0.0}, Vec3{-0.0, -1, 0.2}, Vec3{0, -1, 0}, Vec3{-0.0, -1, -0.0}}) {
    const LightFrame f = LightFrame::fromDirection(d);
    const LightFrame plus = LightFrame::fromDirection(d + Vec3{0, 0, 0});
    for (const Vec3* v : {&f.dir, &f.u, &f.v})
      for (double x : {v->x, v->y, v->z}) EXPECT_FALSE(x == 0 && std::signbit(x)) << "a -0 in the frame of " << d.x << "," << d.z;
    EXPECT_EQ(bits(f.dir), bits(plus.dir));
    EXPECT_EQ(bits(f.u), bits(plus.u));
    EXPECT_EQ(f.u.x, plus.u.x);
    EXPECT_EQ(f.v.y, plus.v.y);
    Scene s;
    s.positions = {{-1, 0, -1}, {1, 0, -1}, {0, 0, 1}};
    s.indices = {0, 1, 2};
    const OrthoGrid g = makeGrid(s, f, 6);
    for (double x : {g.origin.x, g.origin.y, g.origin.z, g.u0, g.v0, g.d0}) EXPECT_FALSE(x == 0 && std::signbit(x));
  }
}

}  // namespace cpvs
