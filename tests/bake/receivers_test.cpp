// Declared receivers against a brute force: every voxel that any declared receiver's
// lookup reads (its own point, normal offset and PCF footprint, each width up to the
// declared one) has, in a bake that knows the receivers, the value the texel's
// classification requires; and the bake is smaller than one for receivers everywhere.
#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <array>
#include <map>
#include <random>

#include "cpvs/bake/bake.h"
#include "cpvs/bake/bake_lights.h"
#include "cpvs/bake/light_plan.h"
#include "cpvs/bake/bake_plan.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/column_masks.h"
#include "cpvs/bake/stage_times.h"
#include "cpvs/bake/texel_slices.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/bake/raster_slices.h"
#include "bake/receiver_reads.h"
#include "cpvs/bake/receivers.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/query/bundle_query.h"
#include "cpvs/query/shadow_query.h"
#include "cpvs/scene/boxes.h"
#include "cpvs/scene/source.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

using testing::appendQuad;

// Open and closed geometry of every kind a level has: a ground sheet, a building without
// a floor, a closed crate, a single-sided thin wall, a slanted roof-like triangle, and a
// floating sheet facing down.
Scene testScene() {
  Scene s;
  appendQuad(s, {-10, 0, -10}, {-10, 0, 10}, {10, 0, 10}, {10, 0, -10});  // ground, facing +y
  const Vec3 lo{-6, 0, -6}, hi{-1, 4, -1};                                   // building walls and roof, outward
  appendQuad(s, {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z});
  appendQuad(s, {hi.x, lo.y, lo.z}, {lo.x, lo.y, lo.z}, {lo.x, hi.y, lo.z}, {hi.x, hi.y, lo.z});
  appendQuad(s, {hi.x, lo.y, hi.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z}, {hi.x, hi.y, hi.z});
  appendQuad(s, {lo.x, lo.y, lo.z}, {lo.x, lo.y, hi.z}, {lo.x, hi.y, hi.z}, {lo.x, hi.y, lo.z});
  appendQuad(s, {lo.x, hi.y, lo.z}, {lo.x, hi.y, hi.z}, {hi.x, hi.y, hi.z}, {hi.x, hi.y, lo.z});
  appendBox(s, {2, 0, 2}, {4, 2, 5});                                       // a closed crate
  appendQuad(s, {0, 0, 6}, {6, 0, 6}, {6, 3, 6.05}, {0, 3, 6.05});          // a thin wall, one side
  const uint32_t t = uint32_t(s.positions.size());
  for (const Vec3& p : {Vec3{3, 1, -3}, Vec3{8, 5, -8}, Vec3{6, 1, -1}}) s.positions.push_back(p);
  for (uint32_t i : {0u, 1u, 2u}) s.indices.push_back(t + i);
  appendQuad(s, {-9, 6, 3}, {-4, 6, 3}, {-4, 6, 8}, {-9, 6, 8});            // a floating sheet, facing down
  finalizeScene(s);
  return s;
}

// A receiver lookup: a point, the normal it is queried with, and a filter width.
struct Lookup {
  Vec3 point, normal;
  int pcf;
};

std::vector<Lookup> surfaceLookups(const Scene& s, const ReceiverDeclaration& d, std::mt19937_64& rng, int perTriangle) {
  const int maxPcf = d.maxPcf;
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Lookup> out;
  const std::vector<uint8_t> receiving = receivingSides(s, d);
  for (size_t t = 0; t < s.triangleCount(); ++t) {
    const Vec3 a = s.vertex(t, 0), b = s.vertex(t, 1), c = s.vertex(t, 2);
    const Vec3 n = normalize(cross(b - a, c - a));
    const uint8_t sides = receiving[t];
    for (int k = 0; k < perTriangle && sides != 0; ++k) {
      double x = u(rng), y = u(rng);
      if (x + y > 1) x = 1 - x, y = 1 - y;
      if (k % 8 == 0) x = 0;  // on an edge
      if (k % 16 == 1) x = y = 0;  // on a vertex
      const Vec3 p = a + (b - a) * x + (c - a) * y;
      const int pcf = 1 + 2 * int(rng() % uint64_t(maxPcf / 2 + 1));
      // A normal as an engine holds it: in float.
      const Vec3 nf{double(float(n.x)), double(float(n.y)), double(float(n.z))};
      if (sides & 1) out.push_back({p, nf, pcf});
      if (sides & 2) out.push_back({p, -nf, pcf});
    }
  }
  return out;
}

std::vector<Lookup> volumeLookups(const Scene& volume, int maxPcf, std::mt19937_64& rng, int count) {
  std::uniform_real_distribution<double> u(0, 1), sym(-1, 1);
  Vec3 lo, hi;
  sceneBounds(volume, lo, hi);
  std::vector<Lookup> out;
  while (int(out.size()) < count) {
    const Vec3 p{lo.x + (hi.x - lo.x) * u(rng), lo.y + (hi.y - lo.y) * u(rng), lo.z + (hi.z - lo.z) * u(rng)};
    // Keep points inside one of the boxes (each is its own closed part of 12 triangles).
    bool inside = false;
    for (size_t b = 0; b < volume.triangleCount() / 12 && !inside; ++b) {
      Vec3 bl = volume.vertex(12 * b, 0), bh = bl;
      for (size_t t = 12 * b; t < 12 * b + 12; ++t)
        for (int c = 0; c < 3; ++c) {
          const Vec3 v = volume.vertex(t, c);
          bl = {std::min(bl.x, v.x), std::min(bl.y, v.y), std::min(bl.z, v.z)};
          bh = {std::max(bh.x, v.x), std::max(bh.y, v.y), std::max(bh.z, v.z)};
        }
      inside = p.x >= bl.x && p.x <= bh.x && p.y >= bl.y && p.y <= bh.y && p.z >= bl.z && p.z <= bh.z;
    }
    if (!inside) continue;
    Vec3 n{sym(rng), sym(rng), sym(rng)};
    if (out.size() % 7 == 0) n = Vec3{};                       // no offset
    if (out.size() % 7 == 1) n = Vec3{0, double(rng() % 2) * 2 - 1, 0};  // straight up or down
    out.push_back({p, n, 1 + 2 * int(rng() % uint64_t(maxPcf / 2 + 1))});
  }
  return out;
}

// Points of the declaration's ground layer: on walkable triangles (faces, edges, vertices),
// raised between the layer's bottom and top (both included), with any normal.
std::vector<Lookup> layerLookups(const Scene& s, const ReceiverDeclaration& d, std::mt19937_64& rng, int perTriangle) {
  std::uniform_real_distribution<double> u(0, 1), sym(-1, 1);
  std::vector<Lookup> out;
  for (size_t t = 0; t < s.triangleCount(); ++t) {
    if (!walkable(s, d, t)) continue;
    const Vec3 a = s.vertex(t, 0), b = s.vertex(t, 1), c = s.vertex(t, 2);
    for (int k = 0; k < perTriangle; ++k) {
      double x = u(rng), y = u(rng);
      if (x + y > 1) x = 1 - x, y = 1 - y;
      if (k % 8 == 0) x = 0;
      if (k % 16 == 1) x = y = 0;
      const double span = d.groundLayer - d.groundLayerFrom;
      const double h = d.groundLayerFrom + (k % 5 == 0 ? span : k % 5 == 1 ? 0 : span * u(rng));
      Vec3 n{sym(rng), sym(rng), sym(rng)};
      if (k % 7 == 0) n = Vec3{};
      if (k % 7 == 1) n = Vec3{0, double(rng() % 2) * 2 - 1, 0};
      out.push_back({a + (b - a) * x + (c - a) * y + Vec3{0, h, 0}, n, 1 + 2 * int(rng() % uint64_t(d.maxPcf / 2 + 1))});
    }
  }
  return out;
}

// Checks every voxel the lookups read: returns the reads checked; adds failures.
uint64_t checkReads(const ShadowQuery& q, const TexelSlices& truth, const std::vector<Lookup>& lookups, int& failures) {
  const int64_t R = int64_t(q.lightGrid().side());
  uint64_t checked = 0;
  for (const Lookup& l : lookups) {
    const VoxelCoord v = q.voxelOf(l.point, l.normal, l.pcf);
    const int r = l.pcf / 2;
    if (v.z < 0) continue;  // in front of the grid: lit without a read
    if (q.spot() && v.z >= R) continue;  // beyond a spot light's far end (or behind it): dark without a read
    const int64_t z = std::min(v.z, R - 1);
    for (int dy = -r; dy <= r; ++dy)
      for (int dx = -r; dx <= r; ++dx) {
        const int64_t x = v.x + dx, y = v.y + dy;
        if (x < 0 || y < 0 || x >= R || y >= R) continue;
        const size_t t = size_t(y * R + x);
        const bool mustLight = z < int64_t(truth.firstUndefined[t]), mustShadow = z >= int64_t(truth.firstShadowed[t]);
        if (!mustLight && !mustShadow) continue;  // inside closed geometry: free for everyone
        ++checked;
        const bool shadowed = q.voxelShadowed({x, y, z});
        if (shadowed != mustShadow && failures++ < 10)
          ADD_FAILURE() << "lookup at (" << l.point.x << ", " << l.point.y << ", " << l.point.z << ") normal ("
                        << l.normal.x << ", " << l.normal.y << ", " << l.normal.z << ") pcf " << l.pcf
                        << " reads voxel (" << x << ", " << y << ", " << z << "): " << (shadowed ? "shadowed" : "lit")
                        << ", must be " << (mustShadow ? "shadowed" : "lit");
      }
  }
  return checked;
}

Dag bake(const Scene& scene, const OrthoGrid& grid, BakeOptions options, const ReceiverDeclaration& d) {
  options.receivers = d.kind;
  options.receiverPcf = uint8_t(d.maxPcf);
  const BakeScene prepared(scene, grid, options.renderer, 0, d);
  return bakeGrid(prepared, options);
}

uint64_t bytesOf(const Dag& dag, const OrthoGrid& grid) {
  CpvsArtifact a;
  a.grid = grid;
  a.dag = dag;
  return encodeCpvs(a, false).size();
}

// The SIMD kernel of a surface's reads along a row against the scalar statement it
// replaces, column by column: random planes, offsets, cuts and old ranges (lit, free and
// shadowed columns, reads below, across and behind them, none at all), runs of every
// length around the vector widths, at negative and large x; on every SIMD target compiled.
TEST(ReceiverReads, ARunAppliesEachColumnAsTheScalarLoop) {
  for (int64_t target : hwy::SupportedAndGeneratedTargets()) {
    SCOPED_TRACE(hwy::TargetName(target));
    hwy::SetSupportedTargetsForTest(target);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(0, 1);
    for (int trial = 0; trial < 20000; ++trial) {
      const uint32_t R = 1u << (3 + rng() % 18);
      const double top = double(R) - 1;
      const int64_t xa = int64_t(rng() % 4096) - 512, xb = xa + int64_t(rng() % 40);
      PlanarRun run{(u(rng) - 0.2) * R, (u(rng) - 0.5) * (trial % 3 == 0 ? 0.01 : 4), (u(rng) - 0.3) * R,
                    (u(rng) + 0.1) * R, -u(rng) * 12, u(rng) * 12, top, xa, xb};
      if (trial % 7 == 0) run.zHi = run.zLo - 1;  // reads nothing
      const size_t n = size_t(xb - xa + 1);
      std::vector<uint32_t> lo(n), hi(n), newLo(n), newHi(n);
      for (size_t i = 0; i < n; ++i) {
        lo[i] = rng() % 4 == 0 ? R : uint32_t(rng() % R);
        hi[i] = rng() % 4 == 0 ? lo[i] : std::min<uint32_t>(R, lo[i] + uint32_t(rng() % 64));
        newLo[i] = uint32_t(rng() % (lo[i] + 1));
        newHi[i] = std::max<uint32_t>(hi[i], R - uint32_t(rng() % 8));
      }
      std::vector<uint32_t> wantLo = newLo, wantHi = newHi;
      for (size_t i = 0; i < n; ++i) {
        const double z = run.base + run.gx * (double(xa + int64_t(i)) + 0.5);
        const double lower = std::max(run.zLo, z + run.loOff), upper = std::min(run.zHi, z + run.hiOff);
        if (!(lower <= upper) || upper < 0) continue;
        const uint32_t a = uint32_t(std::min(top, std::max(0.0, lower))), b = uint32_t(std::min(top, upper));
        if (a < lo[i]) wantLo[i] = std::max(wantLo[i], std::min(b + 1, lo[i]));
        if (b >= hi[i]) wantHi[i] = std::min(wantHi[i], std::max(a, hi[i]));
      }
      applyPlanarRun(run, lo.data(), hi.data(), newLo.data(), newHi.data());
      ASSERT_EQ(newLo, wantLo) << "trial " << trial;
      ASSERT_EQ(newHi, wantHi) << "trial " << trial;
    }
  }
  hwy::SetSupportedTargetsForTest(0);
}

// The SIMD kernel of a ring's columns row by row against the scalar statement, row by
// row: random half-planes (either sign of dirX, and dirX = 0 with room on either side),
// 0 to 8 directions, runs of every length around the vector widths, at negative and large
// y; on every SIMD target compiled. And that statement against the half-planes themselves:
// a column inside the range meets them all but for rounding, one beside it misses one.
TEST(ReceiverReads, RingRowsAnswerAsTheScalarStatement) {
  const std::vector<int64_t> targets = hwy::SupportedAndGeneratedTargets();
  for (int64_t target : targets) {
    SCOPED_TRACE(hwy::TargetName(target));
    hwy::SetSupportedTargetsForTest(target);
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int trial = 0; trial < 20000; ++trial) {
      double support[8], dirX[8], invDirX[8], dirY[8];
      const uint32_t dirs = uint32_t(rng() % 9);
      const double scale = trial % 2 ? 100.0 : 70000.0;
      for (uint32_t k = 0; k < dirs; ++k) {
        dirX[k] = rng() % 6 == 0 ? 0.0 : u(rng);
        dirY[k] = u(rng);
        invDirX[k] = dirX[k] != 0 ? 1 / dirX[k] : 0;
        support[k] = u(rng) * scale;
      }
      const double xMin = std::floor(u(rng) * scale), xMax = xMin + double(rng() % 4096);
      const RingRows ring{support, dirX, invDirX, dirY, dirs, xMin, xMax};
      const int64_t y0 = int64_t(u(rng) * scale);
      const size_t n = 1 + rng() % 40;
      std::vector<double> x0(n), x1(n);
      ringColumnRows(ring, y0, n, x0.data(), x1.data());
      for (size_t i = 0; i < n; ++i) {
        double w0 = 0, w1 = 0;
        ringColumns(ring, y0 + int64_t(i), w0, w1);
        ASSERT_EQ(x0[i] <= x1[i], w0 <= w1) << "trial " << trial << " row " << i;
        if (w0 <= w1) {
          ASSERT_EQ(x0[i], w0) << "trial " << trial << " row " << i;
          ASSERT_EQ(x1[i], w1) << "trial " << trial << " row " << i;
        }
        if (target != targets.front()) continue;
        const double cy = double(y0 + int64_t(i)) + 0.5;
        auto meets = [&](double c, double slack) {
          for (uint32_t k = 0; k < dirs; ++k)
            if (dirX[k] * (c + 0.5) > support[k] - dirY[k] * cy + slack) return false;
          return c >= xMin && c <= xMax;
        };
        if (w0 <= w1) {
          EXPECT_TRUE(meets(w0, 1e-6 * scale) && meets(w1, 1e-6 * scale)) << "trial " << trial;
          EXPECT_FALSE(meets(w0 - 1, -1e-6 * scale)) << "trial " << trial;
          EXPECT_FALSE(meets(w1 + 1, -1e-6 * scale)) << "trial " << trial;
        }
      }
    }
  }
  hwy::SetSupportedTargetsForTest(0);
}

// A row's rings cut into runs, nested (the common case, cut without a sort) or not:
// each column some ring reaches is in one run, with the least loOff and the greatest
// hiOff of the rings that reach it; no other column is. Random rings, equal ends, one
// ring and kMostRings.
TEST(ReceiverReads, RingRunsGiveEachColumnTheUnionOfItsRings) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> u(-8, 8);
  int nestedRows = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const uint32_t rings = trial % 50 == 0 ? kMostRings : 1 + uint32_t(rng() % 5);
    int64_t from[kMostRings], to[kMostRings];
    double loOff[kMostRings], hiOff[kMostRings];
    const bool nest = trial % 2 == 0;
    int64_t a = int64_t(rng() % 64) - 32, b = a + int64_t(rng() % 12);
    for (uint32_t k = 0; k < rings; ++k) {
      if (nest) {  // each ring inside the next, ends shared now and then
        a -= int64_t(rng() % 3), b += int64_t(rng() % 3);
        from[k] = a, to[k] = b;
      } else {
        from[k] = int64_t(rng() % 64) - 32, to[k] = from[k] + int64_t(rng() % 20);
      }
      loOff[k] = u(rng), hiOff[k] = loOff[k] + std::abs(u(rng));
    }
    bool isNested = true;
    for (uint32_t k = 0; k + 1 < rings; ++k) isNested = isNested && from[k + 1] <= from[k] && to[k] <= to[k + 1];
    nestedRows += isNested;
    std::map<int64_t, std::pair<double, double>> got;
    ringRuns(from, to, loOff, hiOff, rings, [&](int64_t xa, int64_t xb, double lo, double hi) {
      ASSERT_LE(xa, xb) << "trial " << trial;
      for (int64_t x = xa; x <= xb; ++x) {
        ASSERT_TRUE(got.emplace(x, std::make_pair(lo, hi)).second) << "trial " << trial << ": column " << x << " twice";
      }
    });
    for (int64_t x = -80; x <= 120; ++x) {
      double lo = std::numeric_limits<double>::infinity(), hi = -lo;
      bool reached = false;
      for (uint32_t k = 0; k < rings; ++k)
        if (from[k] <= x && x <= to[k]) lo = std::min(lo, loOff[k]), hi = std::max(hi, hiOff[k]), reached = true;
      const auto it = got.find(x);
      ASSERT_EQ(it != got.end(), reached) << "trial " << trial << " column " << x;
      if (reached) {
        ASSERT_EQ(it->second.first, lo) << "trial " << trial << " column " << x;
        ASSERT_EQ(it->second.second, hi) << "trial " << trial << " column " << x;
      }
    }
  }
  EXPECT_GT(nestedRows, 5000);  // both paths taken
  EXPECT_LT(nestedRows, 15000);
}

// The column-sharing passes (fill, greatest and least over rows, select) against their
// scalar loops, at every length around the vector widths, on every SIMD target compiled.
TEST(ReceiverReads, TheSharingPassesAnswerAsTheScalarLoops) {
  for (int64_t target : hwy::SupportedAndGeneratedTargets()) {
    SCOPED_TRACE(hwy::TargetName(target));
    hwy::SetSupportedTargetsForTest(target);
    std::mt19937_64 rng(9);
    for (size_t n = 0; n < 70; ++n) {
      const size_t stride = n + rng() % 5, rows = 1 + rng() % 8;
      std::vector<uint32_t> lo(rows * stride + 1), hi(lo.size()), shared(n), in(n);
      for (size_t i = 0; i < lo.size(); ++i) lo[i] = uint32_t(rng() % (1u << 18)), hi[i] = uint32_t(rng() % (1u << 18));
      for (size_t i = 0; i < n; ++i) {
        shared[i] = rng() % 3 == 0 ? kNoSharedSlice : uint32_t(rng() % (1u << 18));
        in[i] = uint32_t(rng());
      }
      std::vector<uint32_t> filled(n + 1, 7);
      fillSlices(filled.data(), n, 1u << 18);
      for (size_t i = 0; i < n; ++i) ASSERT_EQ(filled[i], 1u << 18);
      ASSERT_EQ(filled[n], 7u);  // nothing past the end
      std::vector<uint32_t> rowLo(n), rowHi(n), out(n);
      rowsMaxMin(lo.data(), hi.data(), stride, rows, n, rowLo.data(), rowHi.data());
      selectShared(shared.data(), in.data(), out.data(), n);
      for (size_t x = 0; x < n; ++x) {
        uint32_t l = lo[x], h = hi[x];
        for (size_t r = 1; r < rows; ++r) l = std::max(l, lo[r * stride + x]), h = std::min(h, hi[r * stride + x]);
        ASSERT_EQ(rowLo[x], l) << "n " << n << " x " << x;
        ASSERT_EQ(rowHi[x], h) << "n " << n << " x " << x;
        ASSERT_EQ(out[x], shared[x] == kNoSharedSlice ? in[x] : shared[x]);
      }
    }
  }
  hwy::SetSupportedTargetsForTest(0);
}

struct Case {
  Vec3 sun;
  int log2R;
  uint64_t depthSlices = 0;  // a grid coarser in depth: its lookups offset further across
};

class ReceiversTest : public ::testing::TestWithParam<Case> {};

TEST_P(ReceiversTest, EveryDeclaredReadHasItsValueAndTheBakeIsSmaller) {
  const Scene scene = testScene();
  const OrthoGrid grid =
      makeGrid(scene, LightFrame::fromDirection(GetParam().sun), GetParam().log2R, GetParam().depthSlices);
  const uint32_t R = uint32_t(grid.resolution());
  BakeOptions options;
  options.log2TileSize = GetParam().log2R - 2;  // 16 tiles: reads cross tile borders
  TexelSlices truth;
  rasterTexelSlices(RasterScene(scene, grid), options.closed, options.exit, 0, 0, R, R, truth);
  const uint64_t everywhere = bytesOf(bake(scene, grid, options, {}), grid);

  std::mt19937_64 rng(GetParam().log2R * 1000 + uint64_t(GetParam().sun.x * 100));
  // The fifth and sixth: a volume that is only a ground layer, on the ground and above it;
  // the seventh: cameras at a point and on a path, their visibility sampled.
  for (int k = 0; k < 7; ++k) {
    const ReceiverKind kind = std::array{ReceiverKind::Surfaces, ReceiverKind::SurfacesTwoSided, ReceiverKind::Volume,
                                         ReceiverKind::Cameras, ReceiverKind::Volume, ReceiverKind::Volume,
                                         ReceiverKind::Cameras}[size_t(k)];
    const bool layer = k >= 4;
    for (int maxPcf : {1, 3, 9}) {
      SCOPED_TRACE(std::string(optionName(kind)) + (layer ? " (ground layer)" : "") + " pcf " + std::to_string(maxPcf));
      ReceiverDeclaration d;
      d.kind = kind;
      d.maxPcf = maxPcf;
      if (layer) {
        d.groundLayer = 1.5;
        d.groundLayerFrom = k == 5 ? 0.4 : 0;
      } else if (kind == ReceiverKind::Volume) {
        appendBox(d.volume, {-9, 0.2, 1}, {9, 2.5, 9});  // over the ground, through the wall and the crate
        appendBox(d.volume, {-8, 4.5, -8}, {0, 5.5, 1});  // above the building's roof
        finalizeScene(d.volume);
      }
      if (k == 6) {
        d.cameraPoints = {Vec3{6, 1, 1}};
        d.cameraPaths = {{Vec3{3, 1, -3}, Vec3{8, 1.5, -3}}};
        d.viewDistance = 8;
        d.cameraVisibility = CameraVisibility::Sampled;
        d.cameraSpacing = 1;
        d.cameraRays = 32;
      } else if (kind == ReceiverKind::Cameras) {
        // Cameras on the +x side of the ground seeing 4 units: the crate, the slanted
        // triangle and the wall's front; a small volume where a character stands.
        d.cameraRegions = {{Vec3{4, 0.5, -2}, Vec3{9, 2, 4}}};
        d.viewDistance = 4;
        appendBox(d.volume, {5, 0.1, -1}, {6, 1.9, 0});
        finalizeScene(d.volume);
      }
      const Dag dag = bake(scene, grid, options, d);
      const ShadowQuery q(grid, PackedDag(dag));
      std::vector<Lookup> lookups = surfaceLookups(scene, d, rng, 600);
      if (d.volume.triangleCount() != 0) {
        const auto inside = volumeLookups(d.volume, maxPcf, rng, 20000);
        lookups.insert(lookups.end(), inside.begin(), inside.end());
      }
      if (layer) {
        const auto above = layerLookups(scene, d, rng, 4000);
        EXPECT_GT(above.size(), 8000u);  // the ground, the roof, the crate's top
        lookups.insert(lookups.end(), above.begin(), above.end());
      }
      int failures = 0;
      const uint64_t checked = checkReads(q, truth, lookups, failures);
      EXPECT_EQ(failures, 0);
      EXPECT_GT(checked, lookups.size() / 2);
      const uint64_t bytes = bytesOf(dag, grid);
      if (kind == ReceiverKind::Surfaces) {
        EXPECT_LT(bytes, everywhere);
      }

      // Freed intervals depend on each texel alone: any tiling gives the same bytes.
      BakeOptions whole = options;
      whole.log2TileSize = GetParam().log2R;
      EXPECT_EQ(bytesOf(bake(scene, grid, whole, d), grid), bytes);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Suns, ReceiversTest,
                         ::testing::Values(Case{{0.3, -1, 0.25}, 7}, Case{{-0.7, -0.35, 0.4}, 7},
                                           Case{{0.05, -1, -0.02}, 8}, Case{{0.2, 0.9, -0.3}, 7},
                                           Case{{1, -0.1, 0.05}, 8}, Case{{0.3, -1, 0.25}, 7, 32},
                                           Case{{-0.7, -0.35, 0.4}, 8, 64}, Case{{1, -0.1, 0.05}, 8, 16}));

// Declared receivers only free voxels, and the aligned rule fills the freed ones towards
// whole slabs and shared columns: on real levels, towns and cities under suns of every
// side, on cubic grids and on one coarser in depth, a bake for surfaces is no larger than
// the bake for everywhere (whose every voxel
// is one valid filling of what surfaces frees). Suns straight down an axis are not among
// them: there a whole city's everywhere DAG is a few flat planes (docs/measured.md).
TEST(Receivers, ASurfacesBakeIsNoLargerThanEverywhereOnRealScenes) {
  const std::string shared = testing::sharedScenesDir();
  ASSERT_FALSE(shared.empty()) << "the shared scenes are beside the project after deploy/setup.sh";
  const char* scenes[] = {"openarena/oa_shouse.obj", "openarena/ctf_compromise.obj", "flightgear/zone_maisons.obj",
                          "loinesg-city/city.obj", "stanford-bunny/bunny.obj", "city:8", "landscape"};
  const Vec3 suns[] = {{-0.31, -1, 0.22}, {0.505259, -0.379456, 0.775066}, {0.7, -0.3, -0.2}};
  for (const char* name : scenes) {
    const std::string path = std::string(name).find('/') == std::string::npos ? name : shared + "/" + name;
    const Scene scene = openScene(path);
    // Each sun on the cubic grid; the peer's also on a grid of slices 4 texels deep.
    for (int k = 0; k < 4; ++k) {
      const Vec3 sun = suns[k < 3 ? k : 1];
      const uint64_t depthSlices = k < 3 ? 0 : 128;
      SCOPED_TRACE(std::string(name) + " sun " + std::to_string(sun.x) + "," + std::to_string(sun.y) + "," +
                   std::to_string(sun.z) + " depth slices " + std::to_string(depthSlices));
      const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection(sun), 9, depthSlices);
      BakeOptions options;
      ReceiverDeclaration surfaces;
      surfaces.kind = ReceiverKind::Surfaces;
      const uint64_t everywhere = bytesOf(bake(scene, grid, options, {}), grid);
      const uint64_t declared = bytesOf(bake(scene, grid, options, surfaces), grid);
      EXPECT_LE(declared, everywhere);
    }
  }
}

// Declared receivers of local lights: on each grid of a spot light and of a point light's
// cube (over the same geometry, from above it, grazing it and inside it), every voxel that
// a declared receiver's lookup reads has the value its texel's classification requires,
// for every kind of declaration and filter width, and any tiling gives the same bytes.
// (Bytes: this scene leaves a light little to free; the city's lamps below.)
struct SpotCase {
  const char* name;
  Light light;
};

void PrintTo(const SpotCase& c, std::ostream* os) { *os << c.name; }

class SpotReceiversTest : public ::testing::TestWithParam<SpotCase> {};

Light spotAt(Vec3 position, Vec3 direction, double coneDeg, int log2R) {
  Light l;
  l.position = position;
  l.direction = direction;
  l.coneDeg = coneDeg;
  l.log2Resolution = log2R;
  return l;
}

Light pointAt(Vec3 position, int log2R) {
  Light l;
  l.kind = LightKind::Point;
  l.position = position;
  l.log2Resolution = log2R;
  return l;
}

TEST_P(SpotReceiversTest, EveryDeclaredReadHasItsValue) {
  const Scene scene = testScene();
  std::mt19937_64 rng(7);
  uint64_t checkedSurfaces = 0, checkedVolumes = 0;
  for (const LightGridPlan& plan : planLightGrids(scene, GetParam().light, 0)) {
    const PerspectiveGrid& grid = plan.grid;
    const uint32_t R = uint32_t(grid.resolution());
    SCOPED_TRACE("grid along (" + std::to_string(grid.frame().dir.x) + ", " + std::to_string(grid.frame().dir.y) + ", " +
                 std::to_string(grid.frame().dir.z) + "), near " + std::to_string(grid.near()));
    BakeOptions options;
    options.log2TileSize = grid.log2Resolution() - 2;  // 16 tiles: reads cross tile borders
    TexelSlices truth;
    rasterTexelSlices(RasterScene(scene, grid, plan.tanCone), options.closed, options.exit, 0, 0, R, R, truth);
    auto bake = [&](BakeOptions o, const ReceiverDeclaration& d) {
      o.receivers = d.kind;
      o.receiverPcf = uint8_t(d.maxPcf);
      return bakeGrid(BakeScene(scene, grid, plan.tanCone, o.renderer, 0, d), o);
    };
    for (int k = 0; k < 5; ++k) {
      const ReceiverKind kind = std::array{ReceiverKind::Surfaces, ReceiverKind::SurfacesTwoSided, ReceiverKind::Volume,
                                           ReceiverKind::Volume, ReceiverKind::Cameras}[size_t(k)];
      const bool layer = k == 3;
      for (int maxPcf : {1, 9}) {
        SCOPED_TRACE(std::string(optionName(kind)) + (layer ? " (ground layer)" : "") + " pcf " + std::to_string(maxPcf));
        ReceiverDeclaration d;
        d.kind = kind;
        d.maxPcf = maxPcf;
        if (layer) {
          d.groundLayer = 1.5;
          d.groundLayerFrom = 0.2;
        } else if (kind == ReceiverKind::Volume) {
          appendBox(d.volume, {-9, 0.2, 1}, {9, 2.5, 9});   // over the ground, through the wall and the crate
          appendBox(d.volume, {-8, 4.5, -8}, {0, 5.5, 1});  // above the building's roof
          appendBox(d.volume, {0, 0.5, -4}, {3, 6.5, -1});  // around the point light
          finalizeScene(d.volume);
        } else if (kind == ReceiverKind::Cameras) {
          d.cameraRegions = {{Vec3{4, 0.5, -2}, Vec3{9, 2, 4}}};
          d.viewDistance = 4;
        }
        const Dag dag = bake(options, d);
        const ShadowQuery q(grid, plan.tanCone, PackedDag(dag));
        std::vector<Lookup> lookups = surfaceLookups(scene, d, rng, 400);
        if (d.volume.triangleCount() != 0) {
          const auto inside = volumeLookups(d.volume, maxPcf, rng, 12000);
          lookups.insert(lookups.end(), inside.begin(), inside.end());
        }
        if (layer) {
          const auto above = layerLookups(scene, d, rng, 2000);
          lookups.insert(lookups.end(), above.begin(), above.end());
        }
        int failures = 0;
        const uint64_t checked = checkReads(q, truth, lookups, failures);
        EXPECT_EQ(failures, 0);
        (kind == ReceiverKind::Volume ? checkedVolumes : checkedSurfaces) += checked;
        // Freed intervals depend on each texel alone: any tiling gives the same DAG.
        BakeOptions whole = options;
        whole.log2TileSize = grid.log2Resolution();
        EXPECT_EQ(bake(whole, d).bytes(), dag.bytes());
      }
    }
  }
  // Every light reads much of what it lights (a point light's faces: some see nothing).
  EXPECT_GT(checkedSurfaces, 20000u);
  EXPECT_GT(checkedVolumes, 20000u);
  std::printf("%s: %llu surface and %llu volume reads checked\n", GetParam().name, (unsigned long long)checkedSurfaces,
              (unsigned long long)checkedVolumes);
}

INSTANTIATE_TEST_SUITE_P(
    Lights, SpotReceiversTest,
    ::testing::Values(SpotCase{"spot_above", spotAt({2, 12, 1}, {-0.2, -1, 0.1}, 55, 7)},
                      SpotCase{"spot_grazing", spotAt({9.5, 1.2, -9}, {-1, -0.05, 1}, 40, 7)},
                      SpotCase{"point_inside", pointAt({1.5, 3, -2.5}, 6)},
                      // A coarse grid over a deep range: every depth in front of the light
                      // may reach slice 0 (receivers are clipped at the light).
                      SpotCase{"point_coarse", [] {
                                 Light l = pointAt({1.5, 3, -2.5}, 4);
                                 l.near = 0.05;
                                 return l;
                               }()}),
    [](const ::testing::TestParamInfo<SpotCase>& info) { return std::string(info.param.name); });

// The city's street lamps (and a point light among the houses) baked for surfaces: every
// lookup of a surface receiver (its receiving side, the geometric normal, each filter
// width up to 9) counts the lit texels of the bundle baked for receivers everywhere,
// unless its footprint reads a voxel inside closed geometry (free in both bakes, each
// fills it its own way: those are compared read by read); and the pool is smaller.
TEST(SpotReceivers, ASurfacesBundleAnswersEverySurfaceLookupAsEverywhere) {
  const Scene scene = openScene("city:3:5");
  std::vector<Light> lights = sceneLights(scene);
  ASSERT_GE(lights.size(), 4u);
  Light point;
  point.kind = LightKind::Point;
  point.position = {30, 9, 30};
  point.range = 30;
  lights.push_back(point);
  const double footprint = defaultFootprint(scene) * 16;
  BakeOptions options;
  options.log2TileSize = 7;
  ReceiverDeclaration d;
  d.kind = ReceiverKind::Surfaces;
  d.maxPcf = 9;
  const LightBundle everywhere = bakeLights(scene, lights, footprint, options, sceneHash(scene));
  BakeOptions declared = options;
  declared.receivers = d.kind;
  declared.receiverPcf = uint8_t(d.maxPcf);
  const LightBundle surfaces = bakeLights(scene, lights, footprint, declared, sceneHash(scene), nullptr, nullptr, nullptr, d);
  EXPECT_EQ(surfaces.receiverHash, receiverHash(d));
  EXPECT_EQ(everywhere.receiverHash, Hash128{});
  EXPECT_LT(surfaces.poolBytes, everywhere.poolBytes);
  std::printf("city:3:5, %zu lights in %zu grids: pool %llu bytes for receivers everywhere, %llu for surfaces (pcf 9)\n",
              lights.size(), surfaces.grids.size(), (unsigned long long)everywhere.poolBytes,
              (unsigned long long)surfaces.poolBytes);
  // A file keeps the declaration.
  const std::vector<uint8_t> bytes = encodeBundle(surfaces, false);
  const LightBundle back = decodeBundle(bytes.data(), bytes.size(), "surfaces.cpvs");
  EXPECT_EQ(back.options.receivers, ReceiverKind::Surfaces);
  EXPECT_EQ(back.options.receiverPcf, 9);
  EXPECT_EQ(back.receiverHash, surfaces.receiverHash);

  const BundleQuery a(surfaces), b(everywhere);
  std::vector<TexelSlices> truth(surfaces.grids.size());
  for (size_t k = 0; k < truth.size(); ++k) {
    const BundleGrid& g = surfaces.grids[k];
    const uint32_t R = uint32_t(g.grid.resolution());
    rasterTexelSlices(RasterScene(scene, g.grid, g.tanCone), options.closed, options.exit, 0, 0, R, R, truth[k]);
  }
  std::mt19937_64 rng(3);
  const std::vector<Lookup> lookups = surfaceLookups(scene, d, rng, 30);
  uint64_t compared = 0, partly = 0, lit = 0, shadowed = 0;
  int failures = 0;
  for (const Lookup& l : lookups)
    for (size_t i = 0; i < lights.size(); ++i) {
      if (length(l.point - lights[i].position) > b.reach(i)) continue;
      const size_t k = b.gridAt(i, l.point);
      const ShadowQuery& qa = a.grid(k);
      const ShadowQuery& qb = b.grid(k);
      const int64_t R = int64_t(surfaces.grids[k].grid.resolution());
      for (int pcf = 1; pcf <= 9; pcf += 2) {
        const uint32_t na = qa.litTexels(l.point, l.normal, pcf), nb = qb.litTexels(l.point, l.normal, pcf);
        const VoxelCoord v = qb.voxelOf(l.point, l.normal, pcf);
        // The voxels it reads (none before near or beyond far), with whether each is free.
        std::vector<std::pair<VoxelCoord, bool>> reads;
        if (v.z >= 0 && v.z < R)
          for (int64_t y = v.y - pcf / 2; y <= v.y + pcf / 2; ++y)
            for (int64_t x = v.x - pcf / 2; x <= v.x + pcf / 2; ++x) {
              if (x < 0 || y < 0 || x >= R || y >= R) continue;
              const size_t t = size_t(y * R + x);
              reads.push_back({{x, y, v.z}, v.z >= int64_t(truth[k].firstUndefined[t]) && v.z < int64_t(truth[k].firstShadowed[t])});
            }
        bool readsFree = false;
        for (const auto& r : reads) readsFree |= r.second;
        if (reads.empty()) continue;
        (nb == 0 ? shadowed : lit) += 1;
        if (!readsFree) {
          ++compared;
          if (na != nb && failures++ < 10)
            ADD_FAILURE() << "light " << i << ", lookup at (" << l.point.x << ", " << l.point.y << ", " << l.point.z
                          << ") normal (" << l.normal.x << ", " << l.normal.y << ", " << l.normal.z << ") pcf " << pcf
                          << ": " << na << " lit texels baked for surfaces, " << nb << " for everywhere";
          continue;
        }
        ++partly;
        for (const auto& [read, free] : reads)
          if (!free && !qa.dark(read.x, read.y) && qa.voxelShadowed(read) != qb.voxelShadowed(read) && failures++ < 10)
            ADD_FAILURE() << "light " << i << ": lookup at (" << l.point.x << ", " << l.point.y << ", " << l.point.z
                          << ") pcf " << pcf << " reads voxel (" << read.x << ", " << read.y << ", " << read.z
                          << ") differently in the two bakes";
      }
    }
  EXPECT_EQ(failures, 0);
  EXPECT_GT(compared, 20000u);
  EXPECT_GT(lit, compared / 20);
  EXPECT_GT(shadowed, compared / 20);
  std::printf("%llu lookups compared by lit count, %llu read by read\n", (unsigned long long)compared,
              (unsigned long long)partly);
}

// On real scenes, a `surfaces` bake answers every surface receiver's lookup, at every
// filter width up to the declared 9, with the lit count of the `everywhere` bake of the
// same scene and sun. Reads inside closed geometry are free in both bakes (each fills them
// its own way): a footprint that reaches one is compared read by read on the others.
struct RealScene {
  const char* name;
  const char* path;  // under shared/scenes
  Vec3 sun;
  int log2R;
};

class SurfacesAsEverywhere : public ::testing::TestWithParam<RealScene> {};

TEST_P(SurfacesAsEverywhere, EverySurfaceLookupCountsTheSameLitTexels) {
  CPVS_SHARED_SCENE_OR_SKIP(dir, "");
  const Scene scene = openScene(dir + GetParam().path);
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection(GetParam().sun), GetParam().log2R);
  const uint32_t R = uint32_t(grid.resolution());
  BakeOptions options;
  options.log2TileSize = GetParam().log2R - 1;  // 4 tiles: footprints cross tile borders
  TexelSlices truth;
  rasterTexelSlices(RasterScene(scene, grid), options.closed, options.exit, 0, 0, R, R, truth);
  ReceiverDeclaration d;
  d.kind = ReceiverKind::Surfaces;
  d.maxPcf = 9;
  const Dag everywhereDag = bake(scene, grid, options, {});
  const Dag surfacesDag = bake(scene, grid, options, d);
  EXPECT_LT(bytesOf(surfacesDag, grid), bytesOf(everywhereDag, grid));
  const ShadowQuery everywhere(grid, PackedDag(everywhereDag)), surfaces(grid, PackedDag(surfacesDag));

  std::mt19937_64 rng(GetParam().log2R);
  const std::vector<Lookup> lookups = surfaceLookups(scene, d, rng, 3);
  ASSERT_GT(lookups.size(), scene.triangleCount());
  // The voxels of the grid a footprint reads, each with whether it lies inside closed
  // geometry (free in either bake); none in front of the grid.
  auto forEachRead = [&](const VoxelCoord& v, int pcf, auto&& visit) {
    if (v.z < 0) return;
    const int64_t z = std::min(v.z, int64_t(R) - 1);
    for (int64_t y = v.y - pcf / 2; y <= v.y + pcf / 2; ++y)
      for (int64_t x = v.x - pcf / 2; x <= v.x + pcf / 2; ++x) {
        if (x < 0 || y < 0 || x >= int64_t(R) || y >= int64_t(R)) continue;
        const size_t t = size_t(y) * R + size_t(x);
        visit(VoxelCoord{x, y, z}, z >= int64_t(truth.firstUndefined[t]) && z < int64_t(truth.firstShadowed[t]));
      }
  };
  uint64_t compared = 0, partly = 0, differ = 0, lit = 0, shadowed = 0;
  int failures = 0;
  for (const Lookup& l : lookups)
    for (int pcf = 1; pcf <= 9; pcf += 2) {
      const uint32_t a = surfaces.litTexels(l.point, l.normal, pcf), b = everywhere.litTexels(l.point, l.normal, pcf);
      const VoxelCoord v = everywhere.voxelOf(l.point, l.normal, pcf);
      (b == 0 ? shadowed : lit) += 1;
      bool readsFree = false;
      forEachRead(v, pcf, [&](const VoxelCoord&, bool free) { readsFree |= free; });
      if (!readsFree) {
        ++compared;
        if (a != b && failures++ < 10)
          ADD_FAILURE() << GetParam().name << ": lookup at (" << l.point.x << ", " << l.point.y << ", " << l.point.z
                        << ") normal (" << l.normal.x << ", " << l.normal.y << ", " << l.normal.z << ") pcf " << pcf
                        << ": " << a << " lit texels in the surfaces bake, " << b << " in the everywhere bake";
        continue;
      }
      ++partly;
      differ += a != b;
      forEachRead(v, pcf, [&](const VoxelCoord& read, bool free) {
        if (!free && surfaces.voxelShadowed(read) != everywhere.voxelShadowed(read) && failures++ < 10)
          ADD_FAILURE() << GetParam().name << ": lookup at (" << l.point.x << ", " << l.point.y << ", " << l.point.z
                        << ") pcf " << pcf << " reads voxel (" << read.x << ", " << read.y << ", " << read.z
                        << ") differently in the two bakes";
      });
    }
  EXPECT_EQ(failures, 0);
  // Most footprints stay outside closed geometry (at 2K, 86 % on the peer's city, where
  // 18 of the 81,104 others count another number of lit texels, all from free voxels;
  // every one on the house), and the lookups see both light and shadow.
  EXPECT_GT(compared, (compared + partly) / 2) << partly << " footprints reach inside closed geometry";
  EXPECT_GT(lit, compared / 20);
  EXPECT_GT(shadowed, compared / 20);
  std::printf("%s at %u: %llu lookups compared by lit count, %llu read by read (%llu of them with another lit count)\n",
              GetParam().name, R, (unsigned long long)compared, (unsigned long long)partly, (unsigned long long)differ);
}

INSTANTIATE_TEST_SUITE_P(RealScenes, SurfacesAsEverywhere,
                         ::testing::Values(RealScene{"peers_city", "loinesg-city/city.obj", {0.505259, -0.379456, 0.775066}, 11},
                                           RealScene{"quake_house", "openarena/oa_shouse.obj", {-0.31, -1, 0.22}, 11}),
                         [](const ::testing::TestParamInfo<RealScene>& info) { return std::string(info.param.name); });

// Each texel's own free range (the reads alone) holds the slice its 8x8 column shares:
// the shared transition only picks, inside what the reads leave free, one slice that all
// 64 texels allow; columns that cannot share keep their texels' ranges.
TEST(Receivers, AColumnsSharedSliceLiesInEachTexelsOwnRange) {
  const Scene scene = testScene();
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection({0.3, -1, 0.25}), 7);
  const uint32_t R = uint32_t(grid.resolution());
  ReceiverDeclaration d;
  d.kind = ReceiverKind::Surfaces;
  d.maxPcf = 3;
  const ReceiverSet set(scene, grid, d);
  TexelSlices shared, own;
  rasterTexelSlices(RasterScene(scene, grid), ClosedMode::Auto, ExitMode::Exact, 0, 0, R, R, shared);
  own = shared;
  set.freeIntervals(0, 0, R, R, shared);
  set.freeIntervals(0, 0, R, R, own, false);
  uint64_t collapsed = 0, wide = 0;
  for (uint32_t by = 0; by < R; by += 8)
    for (uint32_t bx = 0; bx < R; bx += 8) {
      bool same = true;
      for (uint32_t y = by; y < by + 8; ++y)
        for (uint32_t x = bx; x < bx + 8; ++x) {
          const size_t t = size_t(y) * R + x, first = size_t(by) * R + bx;
          ASSERT_LE(own.firstUndefined[t], shared.firstUndefined[t]);
          ASSERT_GE(own.firstShadowed[t], shared.firstShadowed[t]);
          same = same && shared.firstUndefined[t] == shared.firstUndefined[first] &&
                 shared.firstShadowed[t] == shared.firstUndefined[first];
          wide += own.firstShadowed[t] >= own.firstUndefined[t] + 8;
        }
      if (same) {
        ++collapsed;
      } else {  // not shared: each texel as its reads leave it
        for (uint32_t y = by; y < by + 8; ++y)
          for (uint32_t x = bx; x < bx + 8; ++x) {
            const size_t t = size_t(y) * R + x;
            EXPECT_EQ(own.firstUndefined[t], shared.firstUndefined[t]);
            EXPECT_EQ(own.firstShadowed[t], shared.firstShadowed[t]);
          }
      }
    }
  EXPECT_GT(collapsed, 0u);
  EXPECT_GT(wide, uint64_t(R) * R / 4);  // most of the grid is free to the reads alone
}

// The columns, their transitions and their first and full shadows of two blocks' masks.
void expectSameColumns(const ColumnMasks& got, const ColumnMasks& want) {
  EXPECT_EQ(got.columnsX, want.columnsX);
  EXPECT_EQ(got.columnsY, want.columnsY);
  EXPECT_EQ(got.begin, want.begin);
  EXPECT_EQ(got.slice, want.slice);
  EXPECT_EQ(got.mask, want.mask);
  EXPECT_EQ(got.firstShadow, want.firstShadow);
  EXPECT_EQ(got.fullShadow, want.fullShadow);
}

// A block resolved in strips of rows (BakeScene::columnMasks) has the masks of the whole
// block rendered, freed and resolved at once, with either renderer, at a height that is
// no multiple of the strip's and an origin off the tiles'.
TEST(Receivers, StripsOfRowsGiveTheWholeBlocksMasks) {
  const Scene scene = testScene();
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection({0.3, -1, 0.25}), 9);
  const uint32_t R = uint32_t(grid.resolution());
  ReceiverDeclaration d;
  d.kind = ReceiverKind::Surfaces;
  d.maxPcf = 5;
  for (const Renderer renderer : {Renderer::Raster, Renderer::Embree}) {
    SCOPED_TRACE(renderer == Renderer::Raster ? "raster" : "embree");
    const BakeScene prepared(scene, grid, renderer, 0, d);
    BakeOptions options;
    options.renderer = renderer;
    options.receivers = d.kind;
    options.receiverPcf = uint8_t(d.maxPcf);
    const uint64_t x0 = 64, y0 = 8;
    const uint32_t width = 384, height = 296;  // two strips of 128 rows and part of one
    ColumnMasks strips;
    StageTimes times;
    prepared.columnMasks(options, x0, y0, width, height, strips, times);
    TexelSlices whole;
    if (renderer == Renderer::Raster)
      rasterTexelSlices(prepared.raster(), options.closed, options.exit, x0, y0, width, height, whole);
    else
      renderTexelSlices(RayScene(scene, grid.origin), grid, options.closed, options.exit, x0, y0, width, height, whole);
    prepared.receivers().freeIntervals(x0, y0, width, height, whole);
    ColumnMasks want;
    buildColumnMasks(whole, width, height, R, options.undefinedRule, want);
    EXPECT_GT(want.slice.size(), 500u);  // transitions in many columns
    EXPECT_EQ(strips.resolution, want.resolution);
    expectSameColumns(strips, want);
  }
}

// The same on a spot light's grid, whose texels outside the cone are undefined: the
// strips of the cone-cut raster and of the receivers' frustum spans give the masks of
// the whole block.
TEST(SpotReceivers, StripsOfRowsGiveTheWholeBlocksMasks) {
  const Scene scene = openScene("city:3:5");
  const std::vector<Light> lights = sceneLights(scene);
  ASSERT_GE(lights.size(), 1u);
  ReceiverDeclaration d;
  d.kind = ReceiverKind::Surfaces;
  d.maxPcf = 9;
  BakeOptions options;
  options.log2TileSize = 7;
  options.receivers = d.kind;
  options.receiverPcf = uint8_t(d.maxPcf);
  const LightBundle bundle =
      bakeLights(scene, lights, defaultFootprint(scene) * 16, options, sceneHash(scene), nullptr, nullptr, nullptr, d);
  // The largest grid of a spot light (a cone that cuts texels off).
  const BundleGrid* spot = nullptr;
  for (const BundleGrid& g : bundle.grids)
    if (bundle.lights[g.light].light.kind == LightKind::Spot && (!spot || g.grid.resolution() > spot->grid.resolution()))
      spot = &g;
  ASSERT_NE(spot, nullptr);
  const uint32_t R = uint32_t(spot->grid.resolution());
  ASSERT_GE(R, 256u);
  const BakeScene prepared(scene, spot->grid, spot->tanCone, Renderer::Raster, 0, d);
  const uint64_t x0 = 8, y0 = 8;
  const uint32_t width = 240, height = 240;  // a strip of 128 rows and part of one
  ColumnMasks strips;
  StageTimes times;
  prepared.columnMasks(options, x0, y0, width, height, strips, times);
  TexelSlices whole;
  rasterTexelSlices(prepared.raster(), options.closed, options.exit, x0, y0, width, height, whole);
  prepared.receivers().freeIntervals(x0, y0, width, height, whole);
  ColumnMasks want;
  buildColumnMasks(whole, width, height, R, options.undefinedRule, want);
  EXPECT_GT(want.slice.size(), 500u);  // transitions in many columns
  expectSameColumns(strips, want);
}

TEST(Receivers, TilesNoReceiverReadsAreNotRendered) {
  Scene scene;
  appendQuad(scene, {0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {1, 0, 0});
  appendQuad(scene, {30, 0, 30}, {30, 0, 31}, {31, 0, 31}, {31, 0, 30});
  finalizeScene(scene);
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection({0, -1, 0}), 8);
  ReceiverDeclaration d;
  d.kind = ReceiverKind::Surfaces;
  const ReceiverSet set(scene, grid, d);
  EXPECT_TRUE(set.touchesRectangle(0, 0, 256, 256));
  // The two quads lie in opposite corners of the grid: the other corners hold no reads.
  const Vec3 a = grid.voxelFromWorld({0.5, 0, 0.5}), b = grid.voxelFromWorld({30.5, 0, 30.5});
  const uint64_t ax = uint64_t(a.x), ay = uint64_t(a.y), bx = uint64_t(b.x), by = uint64_t(b.y);
  EXPECT_TRUE(set.touchesRectangle(ax, ay, 1, 1));
  EXPECT_TRUE(set.touchesRectangle(bx, by, 1, 1));
  EXPECT_FALSE(set.touchesRectangle(std::min(ax, bx) + 64, std::min(ay, by) + 64, 64, 64));
  EXPECT_FALSE(set.touchesRectangle(std::max(ax, bx) - 32, std::min(ay, by) + 64, 16, 16));
  // Cameras that see only the first quad: the second one's tile holds no reads.
  d.kind = ReceiverKind::Cameras;
  d.cameraRegions = {{Vec3{0, 1, 0}, Vec3{1, 2, 1}}};
  d.viewDistance = 5;
  const ReceiverSet seen(scene, grid, d);
  EXPECT_TRUE(seen.touchesRectangle(ax, ay, 1, 1));
  EXPECT_FALSE(seen.touchesRectangle(bx, by, 1, 1));
  EXPECT_FALSE(seen.touchesRectangle(std::max(ax, bx) - 32, std::max(ay, by) - 32, 64, 64));
}

// The plan records where receivers read (cells of the grid, by their spans' bounds) and
// reads it back; a plan without it, or with anything else there, gives none.
TEST(Receivers, ThePlanRecordsTheirCoverageAndReadsItBack) {
  Scene scene;
  appendQuad(scene, {0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {1, 0, 0});
  appendQuad(scene, {30, 0, 30}, {30, 0, 31}, {31, 0, 31}, {31, 0, 30});
  SceneStats stats = finalizeScene(scene);
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection({0, -1, 0}), 9);
  ReceiverDeclaration d;
  d.kind = ReceiverKind::Surfaces;
  BakeOptions options;
  options.receivers = d.kind;
  const RasterScene raster(scene, grid);
  const ReceiverSet reads(scene, grid, d);
  const BakePlan plan = planBake(scene, stats, options, d, raster, reads);
  ASSERT_EQ(plan.coverageCells, kPlanCoverageCells);
  const uint64_t side = grid.resolution() / plan.coverageCells;
  uint64_t covered = 0;
  for (uint32_t cy = 0; cy < plan.coverageCells; ++cy)
    for (uint32_t cx = 0; cx < plan.coverageCells; ++cx) {
      const bool read = reads.touchesRectangle(cx * side, cy * side, side, side);
      EXPECT_EQ(plan.coverage[cy * plan.coverageCells + cx], read ? 1 : 0) << cx << ", " << cy;
      covered += read;
    }
  EXPECT_GT(covered, 0u);
  EXPECT_LT(covered, 32u);  // two small quads in opposite corners, of 4096 cells
  // Each quad's own cell is covered.
  for (const Vec3& p : {Vec3{0.5, 0, 0.5}, Vec3{30.5, 0, 30.5}}) {
    const Vec3 v = grid.voxelFromWorld(p);
    EXPECT_EQ(plan.coverage[size_t(v.y) / side * plan.coverageCells + size_t(v.x) / side], 1);
  }

  const std::string json = planJson(plan);
  uint32_t cells = 0;
  std::vector<uint8_t> coverage;
  ASSERT_TRUE(planCoverage(json, grid.resolution(), cells, coverage));
  EXPECT_EQ(cells, plan.coverageCells);
  EXPECT_EQ(coverage, plan.coverage);
  // Everywhere records none; damaged coverage is not read.
  const BakePlan everywhere = planBake(scene, stats, BakeOptions{}, ReceiverDeclaration{}, raster, ReceiverSet(scene, grid, {}));
  EXPECT_EQ(everywhere.coverageCells, 0u);
  EXPECT_NE(planJson(everywhere).find("\"coverage\": null"), std::string::npos);
  EXPECT_FALSE(planCoverage(planJson(everywhere), grid.resolution(), cells, coverage));
  EXPECT_TRUE(coverage.empty());
  const size_t rows = json.find("\"rows\": [\"") + 10;
  for (const auto& [at, text] : std::vector<std::pair<size_t, std::string>>{
           {rows, "g"}, {rows + 16, "0"}, {json.find("\"cells\": 64") + 9, "65"}, {json.find("\"cells\": 64") + 9, "0"}}) {
    std::string bad = json;
    bad.replace(at, text.size(), text);
    EXPECT_FALSE(planCoverage(bad, grid.resolution(), cells, coverage)) << bad.substr(at - 10, 40);
  }
  EXPECT_FALSE(planCoverage(json.substr(0, rows + 100), grid.resolution(), cells, coverage));
  EXPECT_FALSE(planCoverage(json, 32, cells, coverage));    // 64 cells cannot cover a grid of 32
}

// The sides a camera region faces within the view distance, by brute force on a quad.
TEST(Receivers, CameraRegionsReceiveTheSidesTheyFace) {
  Scene s;
  appendQuad(s, {0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {1, 0, 0});  // facing +y
  finalizeScene(s);
  ReceiverDeclaration d;
  d.kind = ReceiverKind::Cameras;
  d.viewDistance = 2;
  d.cameraRegions = {{Vec3{0, 1, 0}, Vec3{1, 2, 1}}};  // above
  EXPECT_EQ(receivingSides(s, d)[0], 1);
  d.cameraRegions = {{Vec3{0, -2, 0}, Vec3{1, -1, 1}}};  // below: the back
  EXPECT_EQ(receivingSides(s, d)[0], 2);
  d.cameraRegions.push_back({Vec3{0, 1, 0}, Vec3{1, 2, 1}});
  EXPECT_EQ(receivingSides(s, d)[0], 3);
  d.cameraRegions = {{Vec3{0, 3, 0}, Vec3{1, 4, 1}}};  // above, but 3 away
  EXPECT_EQ(receivingSides(s, d)[0], 0);
  d.cameraRegions = {{Vec3{-1, -1, -1}, Vec3{2, 0, 2}}};  // touching the plane from below only
  EXPECT_EQ(receivingSides(s, d)[0], 2);
  Scene box;
  appendBox(box, {0, 0, 0}, {1, 1, 1});
  finalizeScene(box);
  d.cameraRegions = {{Vec3{-0.5, -0.5, -0.5}, Vec3{1.5, 1.5, 1.5}}};  // around it: every outside
  for (size_t t = 0; t < box.triangleCount(); ++t) EXPECT_EQ(receivingSides(box, d)[t], 1) << t;  // never the inside
}

// Walkable: a front side facing up within the slope; a layer changes the hash.
TEST(Receivers, AGroundLayerCoversWalkableSurfaces) {
  Scene s;
  appendQuad(s, {0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {1, 0, 0});      // level, facing +y
  appendQuad(s, {0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1});      // level, facing -y
  appendQuad(s, {0, 0, 0}, {0, 0.9, 1}, {1, 0.9, 1}, {1, 0, 0});  // 42 degrees
  appendQuad(s, {0, 0, 0}, {0, 1.1, 1}, {1, 1.1, 1}, {1, 0, 0});  // 48 degrees
  appendQuad(s, {0, 0, 0}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0});      // a wall
  appendQuad(s, {0, 0, 0}, {0, 1, 1}, {1, 1, 1}, {1, 0, 0});      // exactly 45 degrees: walkable
  finalizeScene(s);
  ReceiverDeclaration d;
  d.kind = ReceiverKind::Volume;
  std::vector<bool> expected{true, true, false, false, true, true, false, false, false, false, true, true};
  for (size_t t = 0; t < s.triangleCount(); ++t) EXPECT_FALSE(walkable(s, d, t)) << t;  // no layer declared
  d.groundLayer = 2;
  for (size_t t = 0; t < s.triangleCount(); ++t) EXPECT_EQ(walkable(s, d, t), expected[t]) << t;
  EXPECT_NO_THROW(checkReceiverDeclaration(d));
  const Hash128 h45 = receiverHash(d);
  d.groundSlopeDeg = 50;
  expected[6] = expected[7] = true;
  for (size_t t = 0; t < s.triangleCount(); ++t) EXPECT_EQ(walkable(s, d, t), expected[t]) << t;
  EXPECT_NE(receiverHash(d), h45);
  d.groundSlopeDeg = 90;
  EXPECT_THROW(checkReceiverDeclaration(d), InputError);
  d.groundSlopeDeg = 45;
  const OrthoGrid grid = makeGrid(s, LightFrame::fromDirection({0.3, -1, 0.2}), 8);
  d.groundLayer = 2 * std::max(grid.extent, grid.sceneDepthExtent()) * 1.001;
  EXPECT_THROW(ReceiverSet(s, grid, d), InputError);  // taller than the grid: nobody declares that
  d.groundLayer = 2;
  EXPECT_NO_THROW(ReceiverSet(s, grid, d));
  d.groundSlopeDeg = 45;
  d.groundLayer = -1;
  EXPECT_THROW(checkReceiverDeclaration(d), InputError);
  d.groundLayer = 1;
  d.groundLayerFrom = 1;
  EXPECT_THROW(checkReceiverDeclaration(d), InputError);  // a layer from its top
  d.groundLayerFrom = 0.5;
  EXPECT_NO_THROW(checkReceiverDeclaration(d));
  d.groundLayerFrom = 0;
  d.groundLayer = 1;
  d.kind = ReceiverKind::Surfaces;
  EXPECT_THROW(checkReceiverDeclaration(d), InputError);  // a layer for surfaces
  // A layer added to a box volume changes its hash.
  ReceiverDeclaration box;
  box.kind = ReceiverKind::Volume;
  appendBox(box.volume, {0, 0, 0}, {1, 1, 1});
  finalizeScene(box.volume);
  const Hash128 before = receiverHash(box);
  box.groundLayer = 0.5;
  EXPECT_NE(receiverHash(box), before);
}

TEST(Receivers, BadDeclarationsAreRefused) {
  ReceiverDeclaration d;
  d.kind = ReceiverKind::Volume;
  EXPECT_THROW(checkReceiverDeclaration(d), InputError);  // no volume
  Scene open;
  appendQuad(open, {0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {1, 0, 0});
  finalizeScene(open);
  d.volume = open;
  EXPECT_THROW(checkReceiverDeclaration(d), InputError);  // not closed
  d.kind = ReceiverKind::Surfaces;
  EXPECT_THROW(checkReceiverDeclaration(d), InputError);  // a volume for surfaces
  d.volume = Scene{};
  d.maxPcf = 4;
  EXPECT_THROW(checkReceiverDeclaration(d), InputError);
  d.maxPcf = 11;
  EXPECT_THROW(checkReceiverDeclaration(d), InputError);
  d.maxPcf = 9;
  EXPECT_NO_THROW(checkReceiverDeclaration(d));
  ReceiverDeclaration c;
  c.kind = ReceiverKind::Cameras;
  EXPECT_THROW(checkReceiverDeclaration(c), InputError);  // no region
  c.cameraRegions = {{Vec3{0, 0, 0}, Vec3{1, 1, 1}}};
  EXPECT_THROW(checkReceiverDeclaration(c), InputError);  // no view distance
  c.viewDistance = 10;
  EXPECT_NO_THROW(checkReceiverDeclaration(c));
  c.cameraRegions = {{Vec3{0, 0, 0}, Vec3{1, 0, 1}}};
  EXPECT_THROW(checkReceiverDeclaration(c), InputError);  // empty region
  d.cameraRegions = {{Vec3{0, 0, 0}, Vec3{1, 1, 1}}};
  EXPECT_THROW(checkReceiverDeclaration(d), InputError);  // regions for surfaces
  EXPECT_NE(receiverHash(d), Hash128{});
  EXPECT_EQ(receiverHash(ReceiverDeclaration{}), Hash128{});
}

}  // namespace
}  // namespace cpvs
