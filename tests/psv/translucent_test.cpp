// Translucent casters (seed 003 §3.4): a sun bake leaves them out of the CPVS and stores
// their TOP tree beside it; the artifact keeps it through its bytes, refuses it damaged,
// and an opaque scene's artifact has none.
#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <filesystem>
#include <vector>

#include "cpvs/base/error.h"
#include "cpvs/base/file.h"
#include "cpvs/base/split_mix64.h"
#include "cpvs/dag/packed_dag.h"
#include "cpvs/psv/translucent_tree.h"
#include "cpvs/scene/import.h"
#include "error_testing.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

const Vec3 kSun = normalize(Vec3{0.3, -1, 0.2});

std::vector<Vec3> pointsIn(const Scene& scene, int count, uint64_t seed) {
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  SplitMix64 rng(seed);
  std::vector<Vec3> out;
  for (int i = 0; i < count; ++i)
    out.push_back({lo.x + (hi.x - lo.x) * rng.uniform01(), lo.y + (hi.y - lo.y) * rng.uniform01(),
                   lo.z + (hi.z - lo.z) * rng.uniform01()});
  return out;
}

// The CPVS is the bake of the opaque part alone; the tree beside it holds every translucent
// triangle (none culled) and darkens a point by the product over the panes above it, the
// brute force of NOTES §4.4 against the frusta of exactly those triangles.
TEST(TranslucentCasters, TheSunBakeLeavesThemOutAndCarriesTheirTree) {
  const Scene scene = testing::glassCity();
  ASSERT_TRUE(hasTranslucentMeshes(scene));
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection(kSun), 8);
  BakeOptions options;
  options.log2TileSize = 6;
  const CpvsArtifact art = testing::localArtifact(scene, grid, options);
  EXPECT_EQ(PackedDag(art.dag).words(), PackedDag(testing::bakeWith(opaquePart(scene), grid, options)).words())
      << "the CPVS holds the opaque part's shadows only";
  Scene allOpaque = scene;
  for (SceneMesh& m : allOpaque.meshes) m.transmittance = {0, 0, 0};
  EXPECT_NE(PackedDag(art.dag).words(), PackedDag(testing::bakeWith(allOpaque, grid, options)).words())
      << "opaque, the glass would have cast hard shadows";
  ASSERT_TRUE(art.translucent);
  const TopTree& tree = *art.translucent;
  const TranslucentCasters glass = translucentCasters(scene);
  EXPECT_EQ(tree.frustumCount(), glass.triangleCount()) << "front-face culling is off: the box casts with both sides";
  EXPECT_EQ(tree.buildStats().culled, 0u);
  size_t underOne = 0, underTwo = 0;
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  const double hair = 1e-4 * length(hi - lo);
  for (const Vec3& p : pointsIn(scene, 40000, 3)) {
    // Brute force: each translucent triangle whose shadow prism holds p, by exact geometry
    // in double (away from its boundary by a hair).
    std::array<double, 3> want{1, 1, 1};
    int holding = 0;
    bool nearBoundary = false;
    for (size_t t = 0; t < glass.triangleCount(); ++t) {
      const Vec3 a = glass.positions[glass.indices[3 * t]], b = glass.positions[glass.indices[3 * t + 1]],
                 c = glass.positions[glass.indices[3 * t + 2]];
      const Vec3 n = cross(b - a, c - a);
      const double along = dot(n, kSun);
      const double towards = dot(n, p - a) / along;  // p - towards * sun lies in the triangle's plane
      const Vec3 q = p - kSun * towards;
      // Distances of q to the three edges' lines (signed: inside positive) and of p to the plane.
      const double d0 = dot(cross(b - a, q - a), n) / (length(b - a) * length(n));
      const double d1 = dot(cross(c - b, q - b), n) / (length(c - b) * length(n));
      const double d2 = dot(cross(a - c, q - c), n) / (length(a - c) * length(n));
      const double plane = std::fabs(dot(n, p - a)) / length(n);
      if (plane < hair || std::fabs(d0) < hair || std::fabs(d1) < hair || std::fabs(d2) < hair) nearBoundary = true;
      if (towards > 0 && d0 > 0 && d1 > 0 && d2 > 0) {
        ++holding;
        for (int k = 0; k < 3; ++k) want[k] *= glass.transmittance[t][k];
      }
    }
    if (nearBoundary) continue;
    underOne += holding == 1;
    underTwo += holding >= 2;
    const std::array<float, 3> got = tree.transmittanceAt(p);
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(got[k], want[k], 1e-6) << holding << " panes above " << p.x << "," << p.y << "," << p.z;
  }
  EXPECT_GT(underOne, 100u);
  EXPECT_GT(underTwo, 100u) << "points under both panes, or behind both sides of the box";
}

// The tree travels in the artifact's bytes (raw and zstd) and comes back answering alike;
// an opaque scene's artifact carries none and keeps its flag clear; damage is refused.
TEST(TranslucentCasters, TheArtifactKeepsTheTreeAndRefusesItDamaged) {
  const Scene scene = testing::glassCity();
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection(kSun), 7);
  const CpvsArtifact art = testing::localArtifact(scene, grid, {});
  for (bool zstd : {false, true}) {
    const std::vector<uint8_t> bytes = encodeCpvs(art, zstd);
    const CpvsArtifact back = decodeCpvs(bytes.data(), bytes.size(), "glass.cpvs");
    ASSERT_TRUE(back.translucent);
    ASSERT_EQ(back.translucent->nodes().size(), art.translucent->nodes().size());
    EXPECT_EQ(std::memcmp(back.translucent->nodes().data(), art.translucent->nodes().data(), art.translucent->bytes()), 0);
    EXPECT_EQ(back.translucent->transmittance(), art.translucent->transmittance());
    for (const Vec3& p : pointsIn(scene, 2000, 8)) ASSERT_EQ(back.translucent->transmittanceAt(p), art.translucent->transmittanceAt(p));
    EXPECT_EQ(encodeCpvs(back, zstd), bytes) << "read and written again, the same bytes";
  }
  const CpvsArtifact opaque = testing::localArtifact(opaquePart(scene), grid, {});
  EXPECT_FALSE(opaque.translucent);
  const std::vector<uint8_t> opaqueBytes = encodeCpvs(opaque, false);
  uint32_t flags;
  std::memcpy(&flags, opaqueBytes.data() + 8, 4);
  EXPECT_EQ(flags, 0u);

  // A tree for another sun than the grid's is refused with a message; damage and a cut
  // file are refused (a hostile tree under a fresh checksum: TopTree's own test).
  CpvsArtifact otherSun = art;
  otherSun.translucent = std::make_shared<const TopTree>(translucentTree(scene, PsvLight::sun(Vec3{0, -1, 0})));
  std::vector<uint8_t> bytes = encodeCpvs(otherSun, false);
  EXPECT_NE(testing::inputErrorOf([&] { decodeCpvs(bytes.data(), bytes.size(), "x.cpvs"); }).find("another light"), std::string::npos);
  bytes = encodeCpvs(art, false);
  for (size_t at : {size_t(8), bytes.size() - 100, bytes.size() - 9}) {
    std::vector<uint8_t> bad = bytes;
    bad[at] ^= 0x10;
    EXPECT_THROW(decodeCpvs(bad.data(), bad.size(), "x.cpvs"), InputError) << at;
  }
  for (size_t size : {bytes.size() - 1, bytes.size() / 2}) EXPECT_THROW(decodeCpvs(bytes.data(), size, "x.cpvs"), InputError);
}

// A scene written as a .glb and read back keeps each mesh's transmittance, and so bakes
// to the same artifact: the farm's uploads take this path.
TEST(TranslucentCasters, AGlbKeepsTheGlass) {
  const Scene scene = testing::glassCity();
  const std::string path = (std::filesystem::temp_directory_path() / "cpvs_glass_city.glb").string();
  testing::writeGlb(scene, path);
  const Scene loaded = loadScene(path, nullptr, ImportOptions{true});
  std::filesystem::remove(path);
  ASSERT_EQ(loaded.meshes.size(), scene.meshes.size());
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    EXPECT_EQ(loaded.meshes[m].transmittance, scene.meshes[m].transmittance) << scene.meshes[m].material;
    EXPECT_EQ(loaded.meshes[m].triangles, scene.meshes[m].triangles);
  }
}

}  // namespace
}  // namespace cpvs
