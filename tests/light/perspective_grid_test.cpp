// The LightGrid mapping of a spot light against its definition (seed 000 §5, NOTES
// §1.2.1-§1.2.4 and §1.4 items 1 and 5): eq. (1)'s slices through one boundary table, the
// round trip, texel rays, the Jacobian against central differences, the cone mask
// against a brute force, the minimal bias at the frustum's corners, refused input, and the
// GPU's one grid record of either projection.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "cpvs/base/error.h"
#include "cpvs/light/gpu_grid.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/light/perspective_grid.h"

namespace cpvs {
namespace {

PerspectiveGrid sampleGrid(int log2R = 8, double tanHalfFov = 1.0, const Vec3& lamp = {1e4, 30, -2e3}) {
  // A lamp far from the world origin, looking down and sideways; far / near = 1000.
  return PerspectiveGrid(lamp, LightFrame::fromDirection({0.3, -1, 0.2}), tanHalfFov, 0.05, 50, log2R);
}

// Continuous voxel coordinates by eq. (1) written out (NOTES §1.2.1).
Vec3 byTheFormula(const PerspectiveGrid& g, const Vec3& p) {
  const Vec3 q = p - g.position();
  const double zv = dot(q, g.frame().dir), R = double(g.resolution()), t = g.tanHalfFov();
  return {(dot(q, g.frame().u) / (zv * t) + 1) * R / 2, (dot(q, g.frame().v) / (zv * t) + 1) * R / 2,
          R * std::log(zv / g.near()) / std::log(g.far() / g.near())};
}

// A random point of the frustum between near and far: a voxel position drawn uniformly.
Vec3 pointInFrustum(const PerspectiveGrid& g, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, double(g.resolution()));
  return g.worldFromVoxel({u(rng), u(rng), u(rng)});
}

TEST(PerspectiveGrid, SlicesFollowEquationOneThroughOneTable) {
  const PerspectiveGrid g = sampleGrid(10);
  const uint64_t R = g.resolution();
  EXPECT_EQ(g.sliceBoundary(0), g.near());
  EXPECT_EQ(g.sliceBoundary(R), g.far());
  const double rho = std::pow(g.far() / g.near(), 1.0 / double(R));
  for (uint64_t k = 0; k < R; ++k) {
    ASSERT_LT(g.sliceBoundary(k), g.sliceBoundary(k + 1)) << k;
    EXPECT_NEAR(g.sliceBoundary(k), g.near() * std::pow(rho, double(k)), 1e-12 * g.sliceBoundary(k)) << k;
    // The shared function: a boundary opens its slice, the depth just below it is the slice before.
    EXPECT_EQ(g.sliceOfDepth(g.sliceBoundary(k)), k);
    if (k > 0) {
      EXPECT_EQ(g.sliceOfDepth(std::nextafter(g.sliceBoundary(k), 0.0)), k - 1);
    }
    // A voxel's depth over its width is the same everywhere: the slice thickness grows by rho.
    if (k > 0) {
      const double ratio = (g.sliceBoundary(k + 1) - g.sliceBoundary(k)) / (g.sliceBoundary(k) - g.sliceBoundary(k - 1));
      EXPECT_NEAR(ratio, rho, 1e-6) << k;
    }
  }
  // Before near (geometry there shadows its column), beyond far, NaN.
  EXPECT_EQ(g.sliceOfDepth(0.01), 0u);
  EXPECT_EQ(g.sliceOfDepth(-3), 0u);
  EXPECT_EQ(g.sliceOfDepth(std::nan("")), 0u);
  EXPECT_EQ(g.sliceOfDepth(g.far()), R);
  EXPECT_EQ(g.sliceOfDepth(1e300), R);
  EXPECT_EQ(g.sliceOfDepth(std::nextafter(g.far(), 0.0)), R - 1);
}

TEST(PerspectiveGrid, VoxelsAreEquationOneAndRoundTrip) {
  const PerspectiveGrid g = sampleGrid();
  std::mt19937_64 rng(5);
  for (int i = 0; i < 20000; ++i) {
    const Vec3 p = pointInFrustum(g, rng);
    const Vec3 v = g.voxelFromWorld(p), f = byTheFormula(g, p);
    EXPECT_NEAR(v.x, f.x, 1e-9);
    EXPECT_NEAR(v.y, f.y, 1e-9);
    // z is linear in depth within a slice: the formula's log is within a slice of it, and
    // both floor to the table's slice of the point's depth.
    EXPECT_EQ(uint32_t(std::floor(v.z)), g.sliceOfDepth(g.depthOf(p)));
    EXPECT_NEAR(v.z, f.z, 1e-2);  // within a slice, a line against the log: at most (rho - 1) / 8
    const Vec3 back = g.worldFromVoxel(v);
    EXPECT_LT(length(back - p), 1e-12 * length(p)) << i;
    EXPECT_NEAR(g.depthOf(p), dot(p - g.position(), g.frame().dir), 1e-12 * length(p));
  }
  // Not in front of the light: NaN. Between the light and near: in front of the grid.
  // Beyond far: behind it.
  const Vec3 behind = g.position() - g.frame().dir * 3;
  EXPECT_TRUE(std::isnan(g.voxelFromWorld(behind).x));
  EXPECT_TRUE(std::isnan(g.voxelFromWorld(g.position()).z));
  EXPECT_TRUE(std::isnan(g.voxelFromWorld(behind).z));
  EXPECT_LT(g.voxelFromWorld(g.position() + g.frame().dir * 0.01).z, 0.0);
  EXPECT_GE(g.voxelFromWorld(g.position() + g.frame().dir * 60).z, double(g.resolution()));
  EXPECT_NEAR(g.voxelFromWorld(g.position() + g.frame().dir * 0.03).x, 128, 1e-7);  // on the axis
}

TEST(PerspectiveGrid, TexelRaysRunThroughTheirTexelsAtUnitDepthSpeed) {
  const PerspectiveGrid g = sampleGrid();
  const Vec3 rel{1e4, 0, -2e3};
  for (uint64_t x : {0u, 1u, 77u, 128u, 255u})
    for (uint64_t y : {0u, 3u, 200u, 255u}) {
      const TexelRay r = g.texelRay(x, y, rel);
      EXPECT_DOUBLE_EQ(dot(r.dir, g.frame().dir), 1.0);
      EXPECT_GT(r.tMax, g.far());
      for (double t : {g.near() * 1.01, 0.7, 3.0, 49.0}) {
        const Vec3 p = rel + r.origin + r.dir * t;
        EXPECT_NEAR(g.depthOf(p), t, 1e-12 * length(p));
        // The lamp is 1e4 from the world origin: a point's rounding there, seen from
        // t units away, is 128 / t texels of 2e-12.
        const Vec3 v = g.voxelFromWorld(p);
        EXPECT_NEAR(v.x, double(x) + 0.5, 1e-9 / t);
        EXPECT_NEAR(v.y, double(y) + 0.5, 1e-9 / t);
        EXPECT_EQ(uint32_t(std::floor(v.z)), g.sliceOfDepth(g.depthOf(p)));
      }
    }
}

TEST(PerspectiveGrid, TheJacobianIsTheMappingsDerivative) {
  // Near the world origin: differences of points 1e4 away would measure their rounding.
  const PerspectiveGrid g = sampleGrid(8, 1.0, {3, 30, -2});
  std::mt19937_64 rng(7);
  std::normal_distribution<double> gauss;
  int checked = 0;
  for (int i = 0; i < 5000; ++i) {
    const Vec3 p = pointInFrustum(g, rng);
    const Vec3 w = normalize(Vec3{gauss(rng), gauss(rng), gauss(rng)});
    const Vec3 j = g.directionToVoxel(p, w);
    // Central differences, small enough to stay inside the point's slice for z.
    const double h = 1e-5 * g.depthOf(p);
    const Vec3 a = g.voxelFromWorld(p + w * h), b = g.voxelFromWorld(p - w * h);
    if (std::floor(a.z) != std::floor(b.z)) continue;  // across a slice boundary: z bends there
    const Vec3 d = (a - b) * (1 / (2 * h));
    for (int c = 0; c < 3; ++c) {
      const double want = c == 0 ? d.x : c == 1 ? d.y : d.z, got = c == 0 ? j.x : c == 1 ? j.y : j.z;
      // Relative to the whole derivative: a component can be small by cancellation.
      EXPECT_NEAR(got, want, 1e-6 * std::max(1.0, length(d))) << "component " << c << " at point " << i;
    }
    ++checked;
  }
  EXPECT_GT(checked, 4900);
  EXPECT_TRUE(std::isnan(g.directionToVoxel(g.position() - g.frame().dir, {0, 1, 0}).x));
}

TEST(PerspectiveGrid, TheConeMaskIsExactPerTexel) {
  const PerspectiveGrid g = sampleGrid(6, 1.2);
  const double R = double(g.resolution()), t = g.tanHalfFov();
  for (double tanCone : {0.3, 0.9, 1.2, 1.7}) {
    uint64_t missed = 0;
    for (uint64_t y = 0; y < g.resolution(); ++y)
      for (uint64_t x = 0; x < g.resolution(); ++x) {
        // Brute force: the smallest angle to the axis over a fine sampling of the texel's
        // square (its edges included), against the cone's.
        double best = INFINITY;
        for (int sy = 0; sy <= 64; ++sy)
          for (int sx = 0; sx <= 64; ++sx) {
            const double a = ((double(x) + sx / 64.0) * 2 / R - 1) * t, b = ((double(y) + sy / 64.0) * 2 / R - 1) * t;
            best = std::min(best, a * a + b * b);
          }
        const bool outside = best > tanCone * tanCone;
        EXPECT_EQ(g.coneMissesTexel(x, y, tanCone), outside) << x << ", " << y << " cone " << tanCone;
        missed += outside;
      }
    if (tanCone < t) {
      EXPECT_GT(missed, 0u);
    }
    if (tanCone >= t * std::sqrt(2.0)) {
      EXPECT_EQ(missed, 0u);
    }
  }
}

// NOTES §1.4 item 5: the lookup voxel of a point on a surface, offset along the surface's
// normal through the Jacobian, lies entirely in front of the surface's plane, at the
// frustum's centre, edges and corners and near near and far: the 8 corners of its cell
// (a piece of a frustum) are on the normal's side of the plane.
TEST(PerspectiveGrid, TheNormalOffsetClearsTheSurfaceEverywhereInTheFrustum) {
  for (double tanHalfFov : {0.4, 1.0, 2.5}) {
    const PerspectiveGrid g = sampleGrid(8, tanHalfFov);
    const double R = double(g.resolution());
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> unit(0, 1);
    std::normal_distribution<double> gauss;
    const double places[] = {0.02, 0.5, 0.98};
    int checked = 0;
    for (int i = 0; i < 30000; ++i) {
      // The centre, the edges and the corners, near the near plane, mid-way and near far.
      const Vec3 v{places[rng() % 3] * R + unit(rng), places[rng() % 3] * R + unit(rng),
                   places[rng() % 3] * (R - 2) + unit(rng)};
      const Vec3 p = g.worldFromVoxel(v);
      Vec3 n = normalize(Vec3{gauss(rng), gauss(rng), gauss(rng)});
      if (dot(n, g.position() - p) <= 0) n = -n;  // a surface that faces the light
      for (int pcf : {1, 9}) {
        const double voxels = 1.5 + (pcf - 1) / 2.0;
        const Vec3 c = g.offsetVoxel(p, n, voxels);
        const Vec3 cell{std::floor(c.x), std::floor(c.y), std::floor(c.z)};
        if (cell.x < 0 || cell.y < 0 || cell.z < 0 || cell.x >= R || cell.y >= R || cell.z >= R) continue;
        for (int corner = 0; corner < 8; ++corner) {
          const Vec3 k = cell + Vec3{double(corner & 1), double((corner >> 1) & 1), double(corner >> 2)};
          const double side = dot(g.worldFromVoxel(k) - p, n);
          EXPECT_GT(side, 0) << "tan " << tanHalfFov << " pcf " << pcf << ": corner " << corner << " of the lookup cell ("
                             << cell.x << ", " << cell.y << ", " << cell.z << ") of voxel (" << v.x << ", " << v.y << ", "
                             << v.z << ") lies behind the surface";
        }
        ++checked;
      }
    }
    EXPECT_GT(checked, 30000);
  }
}

TEST(PerspectiveGrid, BadLightsAreRefused) {
  const LightFrame frame = LightFrame::fromDirection({0, -1, 0});
  auto refused = [&](const Vec3& p, const LightFrame& f, double t, double n, double fa, int r, const char* what) {
    try {
      PerspectiveGrid g(p, f, t, n, fa, r);
      ADD_FAILURE() << "accepted, expected: " << what;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  refused({std::nan(""), 0, 0}, frame, 1, 0.1, 10, 8, "position is not finite");
  refused({0, 0, 0}, LightFrame{{0, -2, 0}, frame.u, frame.v}, 1, 0.1, 10, 8, "not orthonormal");
  refused({0, 0, 0}, LightFrame{frame.dir, frame.dir, frame.v}, 1, 0.1, 10, 8, "not orthonormal");
  refused({0, 0, 0}, frame, 0, 0.1, 10, 8, "field of view");
  refused({0, 0, 0}, frame, 20, 0.1, 10, 8, "field of view");
  refused({0, 0, 0}, frame, std::nan(""), 0.1, 10, 8, "field of view");
  refused({0, 0, 0}, frame, 1, 0, 10, 8, "0 < near < far");
  refused({0, 0, 0}, frame, 1, 10, 10, 8, "0 < near < far");
  refused({0, 0, 0}, frame, 1, 10, 5, 8, "0 < near < far");
  refused({0, 0, 0}, frame, 1, 0.1, INFINITY, 8, "0 < near < far");
  refused({0, 0, 0}, frame, 1, 0.1, 10, 40, "resolution");
  refused({0, 0, 0}, frame, 1, 1, 1 + 1e-13, 12, "too close");
}

}  // namespace
}  // namespace cpvs

namespace cpvs {
namespace {

// The GPU's one grid record, from the one description, for both projections: the sun's
// carries its lookup constants bit for bit (what the CPU's lookups evaluate), a spot
// grid's its apex, frame and depth range; a record maps back to nothing it was not made
// from, and a bad description is refused.
TEST(GpuGrid, EitherProjectionIsOneRecordFromItsDescription) {
  OrthoGrid sun;
  sun.frame = LightFrame::fromDirection({0.3, -1, 0.25});
  sun.origin = {10, -2, 3};
  sun.u0 = -40, sun.v0 = -35, sun.d0 = -60;
  sun.extent = 80, sun.depthExtent = 120;
  sun.log2Resolution = 9;
  const GpuGrid o = gpuGridOf(gridSpecOf(sun), "sun", 0, 0, 0);
  EXPECT_EQ(o.projection, uint32_t(Projection::Orthographic));
  EXPECT_EQ(o.log2Resolution, 9u);
  const LookupMapping m = sun.lookupMapping();
  EXPECT_EQ(std::memcmp(&o.mapping, &m, sizeof m), 0) << "the sun's record holds the CPU's lookup constants";
  EXPECT_EQ(o.tanHalfFov, 0);
  EXPECT_EQ(o.far, 0);

  const PerspectiveGrid spot = sampleGrid(7, 0.7);
  const GpuGrid s = gpuGridOf(gridSpecOf(spot, 0.6), "spot", 96, 1234, 5);
  EXPECT_EQ(s.projection, uint32_t(Projection::Perspective));
  EXPECT_EQ(s.log2Resolution, 7u);
  EXPECT_EQ(s.headerWord, 96u);
  EXPECT_EQ(s.firstBoundary, 1234u);
  EXPECT_EQ(s.light, 5u);
  EXPECT_EQ(Vec3(s.mapping.origin[0], s.mapping.origin[1], s.mapping.origin[2]), spot.position());
  EXPECT_EQ(Vec3(s.mapping.dir[0], s.mapping.dir[1], s.mapping.dir[2]), spot.frame().dir);
  EXPECT_EQ(Vec3(s.mapping.u[0], s.mapping.u[1], s.mapping.u[2]), spot.frame().u);
  EXPECT_EQ(s.mapping.scale[0], 0) << "no orthographic constants in a perspective record";
  EXPECT_EQ(s.tanHalfFov, 0.7);
  EXPECT_EQ(s.tanCone, 0.6);
  EXPECT_EQ(s.near, spot.near());
  EXPECT_EQ(s.far, spot.far());
  EXPECT_EQ(s.logRatio, spot.logRatio());

  GridSpec bad = gridSpecOf(spot, 0.6);
  bad.near = bad.far * 2;
  EXPECT_THROW(gpuGridOf(bad, "bad"), InputError);
  bad = gridSpecOf(sun);
  bad.log2Resolution = 40;
  EXPECT_THROW(gpuGridOf(bad, "bad"), InputError);
}

}  // namespace
}  // namespace cpvs
