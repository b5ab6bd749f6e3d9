// The light bundle (seed 000 §6.1, NOTES §1.4 items 9 and 10): DAGs of any resolutions
// shared in one node pool answer every voxel as each DAG alone does; a bundle of spot and
// point lights over the city round-trips through the file, stores less than separate
// DAGs, gives the same bytes for any tile size, and bad bundles and bad lights are
// refused with what is wrong before any work.
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <xxhash.h>

#include <cstring>
#include <random>

#include "cpvs/bake/bake.h"
#include "cpvs/bake/bake_lights.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/light_plan.h"
#include "cpvs/dag/node_pool.h"
#include "cpvs/eval/camera.h"
#include "cpvs/eval/light_render.h"
#include "cpvs/dag/packed_dag.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/query/bundle_query.h"
#include "cpvs/query/light_tiles.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/scene/boxes.h"
#include "cpvs/scene/source.h"
#include "error_testing.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

using testing::inputErrorOf;

// Three sun bakes of the city, two resolutions, one of them twice.
std::vector<Dag> sunDags() {
  const Scene scene = openScene("city:3");
  std::vector<Dag> dags;
  dags.push_back(testing::bakeWith(scene, makeGrid(scene, LightFrame::fromDirection({0.3, -1, 0.2}), 6), {}));
  dags.push_back(testing::bakeWith(scene, makeGrid(scene, LightFrame::fromDirection({-0.5, -1, 0.1}), 7), {}));
  dags.push_back(dags[0]);
  return dags;
}

TEST(NodePool, SharedNodesAnswerEveryVoxelAsEachDagAlone) {
  const std::vector<Dag> dags = sunDags();
  const NodePool pool = shareNodes({&dags[0], &dags[1], &dags[2]});
  ASSERT_EQ(pool.roots.size(), 3u);
  EXPECT_EQ(pool.levels.size(), dags[1].levels.size()) << "as many levels as the finest DAG";
  auto words = std::make_shared<const std::vector<uint32_t>>(packPool(pool.leaves, pool.levels, pool.roots));
  uint64_t separate = 0;
  for (size_t k = 0; k < dags.size(); ++k) {
    const Dag& d = dags[k];
    EXPECT_EQ(reachableBytes(pool, k), d.bytes()) << "a compressed DAG has no duplicate to share with itself";
    separate += d.bytes();
    const PackedDag view(words, k, reachableBytes(pool, k));
    EXPECT_EQ(view.log2Resolution(), d.log2Resolution);
    const uint64_t R = uint64_t(1) << d.log2Resolution;
    for (uint64_t z = 0; z < R; ++z)
      for (uint64_t y = 0; y < R; ++y)
        for (uint64_t x = 0; x < R; ++x)
          ASSERT_EQ(view.voxelShadowed(x, y, z), dagVoxelShadowed(d, x, y, z)) << "DAG " << k << " at " << x << ", " << y << ", " << z;
  }
  // The repeated DAG costs nothing; the two different ones share some nodes too.
  EXPECT_LT(pool.bytes(), dags[0].bytes() + dags[1].bytes());
  EXPECT_LT(pool.bytes(), separate);
  // Parsing the words gives the pool back.
  const NodePool again = parsePackedPool(*words, 3);
  EXPECT_EQ(packPool(again.leaves, again.levels, again.roots), *words);
  // A pool of one DAG is that DAG's packed layout.
  EXPECT_EQ(packPool(dags[1].leaves, dags[1].levels, {{7, dags[1].roots[0].ref}}), PackedDag(dags[1]).words());
}

TEST(NodePool, DamagedPoolsAreRefused) {
  const std::vector<Dag> dags = sunDags();
  const NodePool pool = shareNodes({&dags[0], &dags[1]});
  const std::vector<uint32_t> good = packPool(pool.leaves, pool.levels, pool.roots);
  auto refusal = [&](auto&& damage) {
    std::vector<uint32_t> w = good;
    damage(w);
    return inputErrorOf([&] { parsePackedPool(w, 2); });
  };
  PackedHeader h1;
  std::memcpy(&h1, good.data() + kPackedHeaderWords, sizeof h1);
  EXPECT_NE(refusal([](auto& w) { w[kPackedHeaderWords + 5] += 2; }).find("disagree on the shared leaves"), std::string::npos);
  EXPECT_NE(refusal([](auto& w) { w[kPackedHeaderWords + 4] += 1; }).find("level counts do not match"), std::string::npos);
  EXPECT_NE(refusal([&](auto& w) { w[kPackedHeaderWords + 10 + 1] += 1; }).find("disagree on level 1"), std::string::npos);
  EXPECT_NE(refusal([&](auto& w) { w[h1.gridWord] ^= 1; }).find("the pointer grid, the reference widths or the padding"), std::string::npos);
  EXPECT_EQ(refusal([](auto&) {}), "");
  EXPECT_NE(inputErrorOf([&] { parsePackedPool(good, 3); }), "") << "three headers where there are two";
}

// Two spot lights and a point light over the city, planned from a footprint.
std::vector<Light> cityLights(const Scene& scene) {
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  const Vec3 c = (lo + hi) * 0.5, e = hi - lo;
  std::vector<Light> lights(3);
  lights[0].name = "flood";
  lights[0].position = c + Vec3{0.1 * e.x, 0.45 * e.y, -0.05 * e.z};
  lights[0].direction = {0.25, -1, 0.15};
  lights[0].coneDeg = 50;
  lights[1].name = "street";
  lights[1].position = c + Vec3{-0.3 * e.x, -0.3 * e.y, 0.2 * e.z};
  lights[1].direction = {1, -0.3, -0.3};
  lights[1].coneDeg = 25;
  lights[1].range = 0.5 * length(e);
  lights[2].name = "bulb";
  lights[2].kind = LightKind::Point;
  lights[2].position = c + Vec3{0.05 * e.x, 0.3 * e.y, 0.02 * e.z};
  lights[2].range = 0.4 * length(e);
  lights[2].colour = {1, 0.8, 0.5};
  return lights;
}

TEST(LightBundle, BakesRoundTripsAndSharesAcrossLights) {
  const Scene scene = openScene("city:3");
  const std::vector<Light> lights = cityLights(scene);
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  const double footprint = length(hi - lo) / 64;
  BakeOptions options;
  options.log2TileSize = 5;
  const LightBundle b = bakeLights(scene, lights, footprint, options, sceneHash(scene));
  ASSERT_EQ(b.lights.size(), 3u);
  ASSERT_EQ(b.grids.size(), 8u) << "two spots and a cube";
  uint64_t separate = 0;
  std::mt19937_64 rng(3);
  for (size_t k = 0; k < b.grids.size(); ++k) {
    const BundleGrid& g = b.grids[k];
    const BakeScene prepared(scene, g.grid, g.tanCone, options.renderer);
    const Dag alone = bakeGrid(prepared, options);
    EXPECT_EQ(g.bytes, alone.bytes()) << "grid " << k;
    separate += alone.bytes();
    const PackedDag view = b.dag(k), single(alone);
    const uint64_t R = g.grid.resolution();
    for (int i = 0; i < 20000; ++i) {
      const uint64_t x = rng() % R, y = rng() % R, z = rng() % R;
      ASSERT_EQ(view.voxelShadowed(x, y, z), single.voxelShadowed(x, y, z)) << "grid " << k;
    }
  }
  EXPECT_LT(b.poolBytes, separate) << "the pool shares nodes across lights";
  EXPECT_EQ(b.lightBytes(2), b.grids[2].bytes + b.grids[3].bytes + b.grids[4].bytes + b.grids[5].bytes +
                                 b.grids[6].bytes + b.grids[7].bytes);

  for (bool zstd : {false, true}) {
    const std::vector<uint8_t> bytes = encodeBundle(b, zstd);
    const LightBundle back = decodeBundle(bytes.data(), bytes.size(), "bundle");
    EXPECT_EQ(*back.pool, *b.pool);
    EXPECT_EQ(back.poolBytes, b.poolBytes);
    EXPECT_EQ(back.plan, b.plan);
    EXPECT_EQ(back.options, b.options);
    ASSERT_EQ(back.lights.size(), b.lights.size());
    for (size_t i = 0; i < b.lights.size(); ++i) {
      EXPECT_EQ(back.lights[i].light.name, b.lights[i].light.name);
      EXPECT_EQ(back.lights[i].light.position, b.lights[i].light.position);
      EXPECT_EQ(back.lights[i].light.colour, b.lights[i].light.colour);
      EXPECT_EQ(back.lights[i].firstGrid, b.lights[i].firstGrid);
    }
    for (size_t k = 0; k < b.grids.size(); ++k) {
      EXPECT_EQ(back.grids[k].grid.near(), b.grids[k].grid.near());
      EXPECT_EQ(back.grids[k].grid.far(), b.grids[k].grid.far());
      EXPECT_EQ(back.grids[k].grid.frame().u, b.grids[k].grid.frame().u);
      EXPECT_EQ(back.grids[k].tanCone, b.grids[k].tanCone);
    }
    EXPECT_EQ(encodeBundle(back, zstd), bytes);
  }
  // A bundle of an older packed layout (1: a word per code and per reference, leaves by
  // word offset; 2: level 0's leaves by 16-bit index): its grids' bytes count its layout.
  // It reads, is packed again in today's layout with today's bytes, and answers as the
  // bundle of today.
  for (uint32_t version : {1u, 2u}) {
    ASSERT_EQ(packedLayoutVersion(*b.pool), kPackedLayoutVersion);
    const NodePool nodes = parsePackedPool(*b.pool, b.grids.size());
    LightBundle older = b;
    older.pool = std::make_shared<const std::vector<uint32_t>>(packPool(nodes.leaves, nodes.levels, nodes.roots, version));
    for (size_t k = 0; k < older.grids.size(); ++k) older.grids[k].bytes = reachableBytes(nodes, k, version);
    older.poolBytes = nodes.bytes(version);
    EXPECT_GT(older.poolBytes, b.poolBytes);
    EXPECT_EQ((*older.pool)[0], version);
    const std::vector<uint8_t> bytes = encodeBundle(older, true);
    const LightBundle back = decodeBundle(bytes.data(), bytes.size(), "older");
    EXPECT_EQ(*back.pool, *b.pool);
    EXPECT_EQ(back.poolBytes, b.poolBytes);
    for (size_t k = 0; k < b.grids.size(); ++k) EXPECT_EQ(back.grids[k].bytes, b.grids[k].bytes);
    const LightBundle regridded = withPointerGrids(back, 2);
    EXPECT_EQ(packedLayoutVersion(*regridded.pool), kPackedLayoutVersion);
    const std::vector<uint8_t> again = encodeBundle(regridded, true);
    EXPECT_NO_THROW(decodeBundle(again.data(), again.size(), "older, regridded"));
    for (size_t k = 0; k < b.grids.size(); ++k) {
      const PackedDag view = back.dag(k), today = b.dag(k);
      const uint64_t R = b.grids[k].grid.resolution();
      for (int i = 0; i < 5000; ++i) {
        const uint64_t x = rng() % R, y = rng() % R, z = rng() % R;
        ASSERT_EQ(view.leafSliceMask(x, y, z), today.leafSliceMask(x, y, z)) << "grid " << k;
      }
    }
  }

  // The pointer grid at any depth, down to none: another layout of the same nodes (the
  // file round-trips it), the same answer at every voxel and for every lookup.
  const BundleQuery deepest(b);
  for (int levels : {0, 1, 3, 5}) {
    const LightBundle shallow = withPointerGrids(b, levels);
    EXPECT_EQ(shallow.poolBytes, b.poolBytes);
    if (levels < 5) {
      EXPECT_LT(shallow.pool->size(), b.pool->size()) << levels << " levels: a smaller grid";
    } else {
      EXPECT_EQ(*shallow.pool, *b.pool) << "bundles are baked with the deepest grid";
    }
    const std::vector<uint8_t> bytes = encodeBundle(shallow, true);
    const LightBundle back = decodeBundle(bytes.data(), bytes.size(), "shallow");
    EXPECT_EQ(*back.pool, *shallow.pool);
    for (size_t k = 0; k < b.grids.size(); ++k) {
      EXPECT_EQ(back.dag(k).header().gridLevels, uint32_t(std::min(levels, packedGridLevels(b.grids[k].grid.log2Resolution()))));
      const PackedDag view = back.dag(k), deep = b.dag(k);
      const uint64_t R = b.grids[k].grid.resolution();
      for (int i = 0; i < 5000; ++i) {
        const uint64_t x = rng() % R, y = rng() % R, z = rng() % R;
        ASSERT_EQ(view.leafSliceMask(x, y, z), deep.leafSliceMask(x, y, z)) << levels << " levels, grid " << k;
      }
    }
    const BundleQuery q(back);
    std::uniform_real_distribution<double> unit(0, 1);
    Vec3 lo, hi;
    sceneBounds(scene, lo, hi);
    for (int i = 0; i < 3000; ++i) {
      const Vec3 p{lo.x + unit(rng) * (hi.x - lo.x), lo.y + unit(rng) * (hi.y - lo.y), lo.z + unit(rng) * (hi.z - lo.z)};
      const Vec3 n{unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5};
      for (size_t l = 0; l < b.lights.size(); ++l)
        for (int pcf : {1, 9}) ASSERT_EQ(q.litTexels(l, p, n, pcf), deepest.litTexels(l, p, n, pcf)) << levels << " levels";
    }
  }
  EXPECT_NE(inputErrorOf([&] { withPointerGrids(b, 6); }), "");

  // Any tile size: the same pool and plan (the options record the tile size); grids baked
  // one after another on one thread give the pool grids baked side by side give.
  options.log2TileSize = 12;
  const LightBundle whole = bakeLights(scene, lights, footprint, options, sceneHash(scene));
  EXPECT_EQ(*whole.pool, *b.pool);
  EXPECT_EQ(whole.plan, b.plan);
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    std::vector<double> seconds;
    const LightBundle serial = bakeLights(scene, lights, footprint, options, sceneHash(scene), nullptr, nullptr, &seconds);
    EXPECT_EQ(*serial.pool, *b.pool);
    ASSERT_EQ(seconds.size(), b.grids.size());
    for (double t : seconds) EXPECT_GT(t, 0);
  }
  // Cancelled from the progress callback: the bake stops with Cancelled.
  size_t calls = 0;
  EXPECT_THROW(bakeLights(scene, lights, footprint, options, sceneHash(scene), nullptr,
                          [&](const Progress& p) {
                            EXPECT_EQ(p.stage, "lights");
                            EXPECT_EQ(p.total, b.grids.size());
                            return ++calls < 3;
                          }),
               Cancelled);
  EXPECT_EQ(calls, 3u);
}

// Tiled culling over a picture of the city's street lamps: the culled picture equals
// shading every light at every pixel bit for bit, every lookup beyond a light's reach
// answers 0 (what makes the culling conservative), and lists over the capacity are
// counted, never cut.
TEST(LightTiles, CulledShadingEqualsEveryLightBitForBit) {
  const Scene scene = openScene("city:6");
  std::vector<Light> lamps = sceneLights(scene);
  ASSERT_GE(lamps.size(), 20u);
  const LightBundle b = bakeLights(scene, lamps, 0.3, BakeOptions{}, sceneHash(scene));
  const BundleQuery q(b);
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  const RayScene rays(scene, (lo + hi) * 0.5);
  const CameraHits hits = traceCamera(scene, rays, Camera::parse("75,40,-30,75,0,75,60"), 160, 100);
  std::vector<Vec3> points;
  std::vector<uint8_t> hit;
  hitPoints(hits, points, hit);
  const LightTiles tiles = cullLights(q, points, hit, 160, 100, 16, 4);
  EXPECT_LT(tiles.lights.size(), size_t(tiles.tilesX) * size_t(tiles.tilesY) * lamps.size() / 2) << "culling culls";
  EXPECT_GT(tiles.overflowing, 0u) << "some tile sees more than 4 lamps";
  uint64_t over = 0;
  for (size_t t = 0; t + 1 < tiles.begin.size(); ++t) over += tiles.begin[t + 1] - tiles.begin[t] > 4;
  EXPECT_EQ(over, tiles.overflowing);
  for (int pcf : {1, 9}) {
    const Image culled = shadeLightTiles(hits, q, tiles, pcf), all = shadeAllLights(hits, q, pcf);
    ASSERT_EQ(culled.pixels.size(), all.pixels.size());
    size_t lit = 0;
    for (size_t i = 0; i < all.pixels.size(); ++i) {
      ASSERT_EQ(std::memcmp(&culled.pixels[i], &all.pixels[i], sizeof(Rgb)), 0) << "pixel " << i << " pcf " << pcf;
      lit += all.pixels[i].r > 0.05f;
    }
    EXPECT_GT(lit, 100u) << "the lamps light the streets";
  }
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal;
  for (size_t i = 0; i < q.lightCount(); ++i)
    for (int k = 0; k < 300; ++k) {
      const Vec3 d = normalize(Vec3{normal(rng), normal(rng), normal(rng)});
      const Vec3 p = q.light(i).light.position + d * (q.reach(i) * (1 + 0.5 * std::abs(normal(rng))));
      for (int pcf : {1, 9}) ASSERT_EQ(q.filtered(i, p, d * -1.0, pcf), 0.0f) << "light " << i << " beyond its reach";
    }
}

// A bulb between a floor and a ceiling: every floor and ceiling point is lit, filtered
// or not, across the seams of its cube's faces (each face's guard band holds the widest
// footprint), and it lights in every direction (a point light has no cone).
/// A point light 5 over the ground, slightly off the axes, reaching 40, at 64 a face.
Light testBulb() {
  Light bulb;
  bulb.kind = LightKind::Point;
  bulb.position = {0.3, 5, -0.2};
  bulb.range = 40;
  bulb.log2Resolution = 6;
  return bulb;
}

TEST(LightBundle, APointLightLightsEveryDirectionAcrossItsFaces) {
  Scene scene;
  testing::appendQuad(scene, {-50, 0, -50}, {-50, 0, 50}, {50, 0, 50}, {50, 0, -50});
  testing::appendQuad(scene, {-50, 10, -50}, {50, 10, -50}, {50, 10, 50}, {-50, 10, 50});
  finalizeScene(scene);
  const LightBundle b = bakeLights(scene, {testBulb()}, 0, BakeOptions{}, sceneHash(scene));
  ASSERT_EQ(b.grids.size(), 6u);
  EXPECT_GT(b.grids[0].grid.tanHalfFov(), 1.0) << "a face's square widened by its guard band";
  const BundleQuery q(b);
  uint64_t points = 0;
  for (double x = -14; x <= 14; x += 0.37)
    for (double z = -14; z <= 14; z += 0.41)
      for (const auto& [y, n] : {std::pair{0.0, Vec3{0, 1, 0}}, std::pair{10.0, Vec3{0, -1, 0}}}) {
        const Vec3 p{x, y, z};
        for (int pcf : {1, 9}) ASSERT_EQ(q.filtered(0, p, n, pcf), 1.0f) << p.x << ", " << p.y << ", " << p.z << " pcf " << pcf;
        const Rgb r = lightRadiance(q, 0, p, n, 9);
        ASSERT_GT(r.r, 0.0f) << p.x << ", " << p.y << ", " << p.z;
        ++points;
      }
  EXPECT_GT(points, 10000u);
}

// A bulb inside a closed glass shade: without its fixture left out the shade darkens all
// it lights; left out by its node's, mesh's or material's name, the bundle is the bundle of
// the scene without the shade, and the plan records the names.
TEST(LightBundle, ALightsFixtureCastsNoneOfItsShadows) {
  Scene bare;
  testing::appendQuad(bare, {-50, 0, -50}, {-50, 0, 50}, {50, 0, 50}, {50, 0, -50});
  bare.meshes = {{"street", "ground", "asphalt", 0, 2}};
  Scene scene = bare;
  appendBox(scene, {-1, 4, -1}, {1, 6, 1});
  scene.meshes.push_back({"lampNode", "shade", "glass", 2, 12});
  finalizeScene(scene);
  finalizeScene(bare);
  const Light bulb = testBulb();
  const double footprint = 0.05;
  const LightBundle reference = bakeLights(bare, {bulb}, footprint, BakeOptions{}, sceneHash(scene));
  const LightBundle shaded = bakeLights(scene, {bulb}, footprint, BakeOptions{}, sceneHash(scene));
  EXPECT_EQ(BundleQuery(shaded).filtered(0, {3, 0, 2}, {0, 1, 0}, 1), 0.0f) << "the shade holds the light in";
  EXPECT_EQ(shaded.plan.find("fixtures"), std::string::npos);
  for (const char* name : {"lampNode", "shade", "glass"}) {
    Light fitted = bulb;
    fitted.exclude = {name};
    const LightBundle b = bakeLights(scene, {fitted}, footprint, BakeOptions{}, sceneHash(scene));
    ASSERT_EQ(b.grids.size(), reference.grids.size());
    for (size_t k = 0; k < b.grids.size(); ++k) {
      EXPECT_EQ(b.grids[k].grid.near(), reference.grids[k].grid.near()) << "planned from the ground, not the shade";
      EXPECT_EQ(b.grids[k].bytes, reference.grids[k].bytes);
    }
    EXPECT_EQ(*b.pool, *reference.pool) << name;
    EXPECT_NE(b.plan.find(std::string("\"fixtures\": [{\"light\": 0, \"exclude\": [\"") + name + "\"]}]"), std::string::npos)
        << b.plan;
    const BundleQuery q(b);
    for (double x = -12; x <= 12; x += 1.3)
      for (double z = -12; z <= 12; z += 1.7) ASSERT_EQ(q.filtered(0, {x, 0, z}, {0, 1, 0}, 3), 1.0f) << x << ", " << z;
  }
  Light unknown = bulb;
  unknown.exclude = {"lampshade"};
  unknown.name = "porch";
  std::vector<double> closest;
  EXPECT_NE(testing::inputErrorOf([&] { planLights(scene, {unknown}, footprint, BakeOptions{}, closest); })
                .find("light 0 (porch): no mesh of the scene is named 'lampshade'"),
            std::string::npos);
  unknown.exclude = {""};
  EXPECT_NE(testing::inputErrorOf([&] { bakeLights(scene, {unknown}, footprint, BakeOptions{}, sceneHash(scene)); })
                .find("a fixture name must be 1 to"),
            std::string::npos);
}

void resealChecksum(std::vector<uint8_t>& b) {
  const uint64_t sum = XXH3_64bits(b.data(), b.size() - 8);
  std::memcpy(b.data() + b.size() - 8, &sum, 8);
}

TEST(LightBundle, BadBundlesAndBadLightsAreRefused) {
  const Scene scene = openScene("city:2");
  std::vector<Light> lights = cityLights(scene);
  lights.resize(1);
  lights[0].log2Resolution = 5;
  const LightBundle b = bakeLights(scene, lights, 0, BakeOptions{}, sceneHash(scene));
  const std::vector<uint8_t> good = encodeBundle(b, false);
  auto refusal = [&](auto&& damage) {
    std::vector<uint8_t> bad = good;
    damage(bad);
    resealChecksum(bad);
    try {
      decodeBundle(bad.data(), bad.size(), "lamps.cpvs");
    } catch (const FormatError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(refusal([](auto&) {}), "");
  // The header: magic, version, flags (12 bytes), options and scene hash (28), receivers
  // (24), the plan (4 + its bytes), then the counts.
  const size_t counts = 12 + 28 + 24 + 4 + b.plan.size();
  EXPECT_NE(refusal([&](auto& v) { v[counts] = 0; }).find("light count 0"), std::string::npos);
  EXPECT_NE(refusal([&](auto& v) { v[counts + 4] = 7; }).find("grid count 7"), std::string::npos);
  EXPECT_NE(refusal([&](auto& v) { v[counts + 8] = 9; }).find("unknown kind"), std::string::npos);
  const size_t cone = counts + 8 + 8 + 48;
  EXPECT_NE(refusal([&](auto& v) { std::memset(v.data() + cone, 0, 8); }).find("cone"), std::string::npos);
  // A node's codes (the low half of its first word) holding code 3.
  PackedHeader h;
  std::memcpy(&h, b.pool->data(), sizeof h);
  const size_t pool = good.size() - 8 - 4 * b.pool->size();
  EXPECT_NE(refusal([&](auto& v) { v[pool + 4 * size_t(h.levelWord[h.internalLevels - 1])] |= 0x03; })
                .find("invalid child code"),
            std::string::npos);
  // Single-light artifacts and bundles are told apart by name.
  std::vector<uint8_t> sun = good;
  sun[4] = 3;
  resealChecksum(sun);
  EXPECT_NE(inputErrorOf([&] { decodeBundle(sun.data(), sun.size(), "sun.cpvs"); }).find("a sun artifact"), std::string::npos);
  EXPECT_NE(inputErrorOf([&] { decodeCpvs(good.data(), good.size(), "lamps.cpvs"); }).find("a light bundle"), std::string::npos);

  // Lights are checked before any work.
  std::vector<Light> many(100000, lights[0]);
  EXPECT_NE(inputErrorOf([&] { bakeLights(scene, many, 1, BakeOptions{}, {}); }).find("at most 4096"), std::string::npos);
  std::vector<Light> two = {lights[0], lights[0]};
  two[1].coneDeg = 0;
  EXPECT_NE(inputErrorOf([&] { bakeLights(scene, two, 1, BakeOptions{}, {}); }).find("light 1"), std::string::npos);
  two[1] = lights[0];
  two[1].position.y += 1e6;
  EXPECT_NE(inputErrorOf([&] { bakeLights(scene, two, 1, BakeOptions{}, {}); }).find("outside the scene's bounds"),
            std::string::npos);
  two[1] = lights[0];
  two[1].name = std::string(300, 'x');
  EXPECT_NE(inputErrorOf([&] { bakeLights(scene, two, 1, BakeOptions{}, {}); }).find("longer than 256"), std::string::npos);
  // Thousands of point lights' grids: the plan stays within what a file records.
  LightBundle big;
  const PerspectiveGrid tiny({0, 0, 0}, LightFrame::fromDirection({1, 0, 0}), 1, 0.1, 10, 3);
  for (int k = 0; k < 4096 * 6; ++k) big.grids.push_back({tiny, 2, uint32_t(k / 6), 64});
  const std::string plan = lightPlanJson(big, {});
  EXPECT_LE(plan.size(), kMaxPlanBytes);
  EXPECT_NE(plan.find("omitted"), std::string::npos);

  // Receivers: the options must name the declaration, which must be valid.
  BakeOptions surfaces;
  surfaces.receivers = ReceiverKind::Surfaces;
  EXPECT_NE(inputErrorOf([&] { bakeLights(scene, lights, 1, surfaces, {}); }).find("the declaration 'everywhere'"),
            std::string::npos);
  ReceiverDeclaration volume;
  volume.kind = ReceiverKind::Volume;
  BakeOptions volumeOptions;
  volumeOptions.receivers = ReceiverKind::Volume;
  EXPECT_NE(inputErrorOf([&] { bakeLights(scene, lights, 1, volumeOptions, {}, nullptr, nullptr, nullptr, volume); })
                .find("'volume' needs a volume"),
            std::string::npos);
}

}  // namespace
}  // namespace cpvs
