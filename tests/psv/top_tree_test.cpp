// The TOP tree (seed 003) against brute force over every frustum with the same
// predicates, against Embree's shadow rays away from shadow boundaries, and its structure.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <vector>

#include "cpvs/base/error.h"
#include "cpvs/base/split_mix64.h"
#include "cpvs/psv/top_tree.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/scene/boxes.h"
#include "cpvs/scene/procedural_city.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

Vec3 randomIn(SplitMix64& rng, const Vec3& lo, const Vec3& hi) {
  return {lo.x + (hi.x - lo.x) * rng.uniform01(), lo.y + (hi.y - lo.y) * rng.uniform01(),
          lo.z + (hi.z - lo.z) * rng.uniform01()};
}

/// A soup of random triangles of every size in the unit box, some sharing edges (strips
/// and fans), a few degenerate ones.
Scene randomSoup(int triangles, uint64_t seed) {
  SplitMix64 rng(seed);
  Scene s;
  const Vec3 lo{0, 0, 0}, hi{1, 1, 1};
  while (int(s.indices.size() / 3) < triangles) {
    const uint32_t base = uint32_t(s.positions.size());
    const int kind = rng.range(0, 9);
    if (kind < 6) {  // a free triangle, small or large
      const Vec3 c = randomIn(rng, lo, hi);
      const double size = kind < 4 ? 0.05 : 0.4;
      for (int i = 0; i < 3; ++i) s.positions.push_back(c + (randomIn(rng, lo, hi) - Vec3{0.5, 0.5, 0.5}) * size);
      s.indices.insert(s.indices.end(), {base, base + 1, base + 2});
    } else if (kind < 9) {  // a strip of 6 triangles sharing edges
      const Vec3 c = randomIn(rng, lo, hi);
      for (int i = 0; i < 8; ++i)
        s.positions.push_back(c + Vec3{0.02 * i, 0.03 * (i % 2) + 0.002 * rng.uniform01(), 0.01 * rng.uniform01()});
      for (uint32_t i = 0; i < 6; ++i) s.indices.insert(s.indices.end(), {base + i, base + i + 1, base + i + 2});
    } else {  // degenerate: a repeated corner
      const Vec3 c = randomIn(rng, lo, hi);
      s.positions.push_back(c);
      s.positions.push_back(c + Vec3{0.1, 0, 0});
      s.indices.insert(s.indices.end(), {base, base + 1, base});
    }
  }
  s.closed.assign(s.indices.size() / 3, 0);
  return s;
}

/// Points of the kinds that make exactness hard: anywhere in the box, on a frustum's
/// shadow planes (through an edge and the light), on a capping plane (the triangle
/// itself) and on the lines of its edges and corners.
std::vector<Vec3> hardPoints(const Scene& s, const PsvLight& light, int count, uint64_t seed) {
  SplitMix64 rng(seed);
  Vec3 lo, hi;
  sceneBounds(s, lo, hi);
  const Vec3 pad = (hi - lo) * 0.1;
  std::vector<Vec3> out;
  while (int(out.size()) < count) {
    const int kind = rng.range(0, 3);
    if (kind == 0 || s.triangleCount() == 0) {
      out.push_back(randomIn(rng, lo - pad, hi + pad));
      continue;
    }
    const size_t t = rng.next() % s.triangleCount();
    const int j = rng.range(0, 2);
    const Vec3 a = s.vertex(t, j), b = s.vertex(t, (j + 1) % 3), c = s.vertex(t, (j + 2) % 3);
    const double u = rng.uniform01();
    Vec3 onTriangle = kind == 1 ? a + (b - a) * u : a + (b - a) * u * rng.uniform01() + (c - a) * (1 - u) * 0.5;
    if (kind == 3) onTriangle = rng.chance(50) ? a : b;
    const double along = rng.uniform01() * 1.5;
    if (light.directional)
      out.push_back(onTriangle + light.vector * (kind == 2 ? 0 : along));
    else
      out.push_back(light.vector + (onTriangle - light.vector) * (kind == 2 ? 1 : 1 + along));
  }
  return out;
}

void expectQueryEqualsBruteForce(const TopTree& tree, const std::vector<Vec3>& points, const char* what) {
  size_t shadowed = 0, mismatches = 0;
  for (const Vec3& p : points) {
    const bool brute = tree.inAnyFrustum(p);
    shadowed += brute;
    if (tree.shadowed(p) != brute && ++mismatches <= 5)
      ADD_FAILURE() << what << ": at (" << p.x << ", " << p.y << ", " << p.z << ") the tree says "
                    << !brute << ", brute force " << brute;
    TopQueryStats stats;
    const TopAnswer bounded = tree.query(p, 24, &stats);
    if (bounded != TopAnswer::Overflow) {
      EXPECT_EQ(bounded == TopAnswer::Shadowed, brute) << what;
    }
    EXPECT_LE(stats.maxStack, 24u);
  }
  EXPECT_EQ(mismatches, 0u) << what;
  // The points must test both answers.
  EXPECT_GT(shadowed, points.size() / 20) << what;
  EXPECT_LT(shadowed, points.size() - points.size() / 20) << what;
}

TEST(TopTree, AnswersAsTheBruteForceOverEveryFrustum) {
  const Scene soup = randomSoup(1500, 7);
  const PsvLight lights[] = {PsvLight::sun(normalize(Vec3{0.3, -1, 0.45})), PsvLight::sun(Vec3{0, 0, -1}),
                             PsvLight::point(Vec3{0.5, 1.6, 0.4}), PsvLight::point(Vec3{0.5, 0.5, 0.5})};
  int which = 0;
  for (const PsvLight& light : lights) {
    for (int variant = 0; variant < 3; ++variant) {
      TopTreeOptions options;
      options.seed = 11 + uint64_t(variant);
      options.wedges = variant != 1;
      options.randomOrder = variant != 2;
      const TopTree tree = TopTree::build(soup, light, options);
      EXPECT_GT(tree.buildStats().degenerate, 0u);
      const std::string what = "light " + std::to_string(which) + " variant " + std::to_string(variant);
      expectQueryEqualsBruteForce(tree, hardPoints(soup, light, 40000, 3 + uint64_t(which)), what.c_str());
    }
    ++which;
  }
}

TEST(TopTree, AnswersAsTheBruteForceOnTheCity) {
  const Scene city = makeProceduralCity(3, 2);
  Vec3 lo, hi;
  sceneBounds(city, lo, hi);
  const Vec3 lamp{lo.x + 0.4 * (hi.x - lo.x), hi.y + 0.2 * (hi.y - lo.y), lo.z + 0.3 * (hi.z - lo.z)};
  for (const PsvLight& light : {PsvLight::sun(normalize(Vec3{0.505259, -0.379456, 0.775066})), PsvLight::point(lamp)}) {
    for (bool ffc : {true, false}) {
      TopTreeOptions options;
      options.frontFaceCulling = ffc;
      const TopTree tree = TopTree::build(city, light, options);
      EXPECT_EQ(tree.buildStats().culled > 0, ffc);
      expectQueryEqualsBruteForce(tree, hardPoints(city, light, 30000, 5), ffc ? "city, culled" : "city");
    }
  }
}

/// Translucent casters: the walk multiplies the transmittance of every frustum holding a
// point, as the brute force over every frustum does (up to float rounding: the orders
// differ), and a bounded stack says when it does not suffice.
TEST(TopTree, TransmittanceIsTheProductOverEveryFrustumHoldingThePoint) {
  const Scene soup = randomSoup(1200, 21);
  SplitMix64 rng(5);
  std::vector<std::array<float, 3>> tint(soup.triangleCount());
  for (auto& t : tint) t = {float(0.2 + 0.8 * rng.uniform01()), float(0.2 + 0.8 * rng.uniform01()), float(rng.uniform01())};
  TopTreeOptions options;
  options.frontFaceCulling = false;
  for (const PsvLight& light : {PsvLight::sun(normalize(Vec3{0.3, -1, 0.45})), PsvLight::point(Vec3{0.5, 1.6, 0.4})}) {
    TopTree tree = TopTree::build(soup, light, options);
    tree.setTransmittance(tint);
    size_t behindSeveral = 0, overflows = 0;
    for (const Vec3& p : hardPoints(soup, light, 20000, 9)) {
      std::array<double, 3> want{1, 1, 1};
      const std::vector<uint32_t> holding = tree.frustaHolding(p);
      for (uint32_t k : holding)
        for (int c = 0; c < 3; ++c) want[c] *= tree.transmittance()[k][c];
      behindSeveral += holding.size() >= 2;
      const std::array<float, 3> got = tree.transmittanceAt(p);
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(got[c], want[c], 1e-6 * want[c] + 1e-30) << holding.size() << " frusta";
      EXPECT_EQ(holding.empty(), !tree.shadowed(p));
      std::array<float, 3> bounded;
      if (tree.transmittanceAt(p, 5, bounded) == TopAnswer::Overflow) {
        ++overflows;
      } else {
        EXPECT_EQ(bounded, got);
      }
    }
    EXPECT_GT(behindSeveral, 1000u) << "points behind several casters";
    EXPECT_GT(overflows, 0u) << "a stack of 5 does not hold every walk";
  }
  TopTree tree = TopTree::build(soup, PsvLight::sun(Vec3{0, -1, 0}), options);
  EXPECT_THROW(tree.setTransmittance({}), InputError);
  tint[3][1] = 1.5f;
  EXPECT_THROW(tree.setTransmittance(tint), InputError);
}

// A product of transmittances below the least normal float is 0, as a device that flushes
// subnormals makes it; a subnormal transmittance is refused.
TEST(TopTree, TransmittanceNeverGoesSubnormal) {
  Scene panes;
  for (int k = 0; k < 3; ++k) {
    const double y = 1 + k;
    const uint32_t base = uint32_t(panes.positions.size());
    for (const Vec3& p : {Vec3{-1, y, -1}, Vec3{-1, y, 1}, Vec3{1, y, 1}, Vec3{1, y, -1}}) panes.positions.push_back(p);
    for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) panes.indices.push_back(base + i);
  }
  TopTreeOptions options;
  options.frontFaceCulling = false;
  TopTree tree = TopTree::build(panes.positions, panes.indices, {}, PsvLight::sun({0, -1, 0}), options);
  tree.setTransmittance(std::vector<std::array<float, 3>>(6, {1e-15f, 1e-12f, 0.5f}));
  const std::array<float, 3> t = tree.transmittanceAt({0.1, 0, 0.2});
  EXPECT_EQ(t[0], 0.0f) << "1e-45 is subnormal";
  EXPECT_GE(t[1], std::numeric_limits<float>::min()) << "1e-36 is a normal float";
  EXPECT_EQ(t[2], 0.125f);
  EXPECT_THROW(tree.setTransmittance(std::vector<std::array<float, 3>>(6, {1e-40f, 1, 1})), InputError);
}

// A tree as stored answers as the tree built, and nothing a walk could trip on is taken:
// a child that points back or elsewhere than a frustum, a frustum with two parents or
// none, a broken chain of planes, a non-finite plane, a negative wedge, a transmittance
// outside [0, 1], a light or margin that is not finite.
TEST(TopTree, ATreeAsStoredAnswersAsBuiltAndHostileNodesAreRefused) {
  const Scene soup = randomSoup(600, 33);
  TopTreeOptions options;
  options.frontFaceCulling = false;
  const PsvLight sun = PsvLight::sun(normalize(Vec3{0.3, -1, 0.45}));
  TopTree built = TopTree::build(soup, sun, options);
  std::vector<std::array<float, 3>> tint(soup.triangleCount(), {0.5f, 0.25f, 1.0f});
  built.setTransmittance(tint);
  auto stored = [&](std::vector<TopNode> nodes, std::vector<std::array<float, 3>> t) {
    return TopTree::fromNodes(std::move(nodes), built.light(), built.origin(), built.buildTolerance(), built.queryMargin(), std::move(t));
  };
  const TopTree back = stored(built.nodes(), built.transmittance());
  for (const Vec3& p : hardPoints(soup, sun, 20000, 4)) {
    ASSERT_EQ(back.shadowed(p), built.shadowed(p));
    ASSERT_EQ(back.transmittanceAt(p), built.transmittanceAt(p));
  }
  EXPECT_EQ(TopTree::fromNodes({TopNode{}}, sun, {}, 1, 1).root(), 0u) << "no frustum: every point lit";

  using Mutation = std::function<void(std::vector<TopNode>&, std::vector<std::array<float, 3>>&)>;
  const size_t last = built.nodes().size() - 1;
  uint32_t withChild = 0;  // a capping plane with a child
  for (uint32_t i = 4; i < last && !withChild; i += 4)
    if (built.nodes()[i].pos) withChild = i;
  ASSERT_NE(withChild, 0u);
  const std::vector<std::pair<const char*, Mutation>> hostile{
      {"a child before its parent", [&](auto& n, auto&) { n[withChild].pos = 1; }},
      {"a child not a frustum", [&](auto& n, auto&) { n[withChild].pos += 1; }},
      {"a child past the nodes", [&](auto& n, auto&) { n[withChild].pos = uint32_t(last + 4); }},
      {"two parents", [&](auto& n, auto&) { n[1].inter = n[1].inter ? n[1].inter : n[1].pos, n[1].pos = n[1].inter; }},
      {"a frustum hanging nowhere", [&](auto& n, auto&) { n[withChild].pos = 0; }},
      {"a broken chain", [&](auto& n, auto&) { n[2].neg = 4; }},
      {"a plane not finite", [&](auto& n, auto&) { n[7].plane[2] = std::numeric_limits<float>::quiet_NaN(); }},
      {"a negative wedge", [&](auto& n, auto&) { n[6].wedge = -1; }},
      {"the leaf with a child", [&](auto& n, auto&) { n[0].pos = 5; }},
      {"nodes not 4 a frustum", [&](auto& n, auto&) { n.pop_back(); }},
      {"a transmittance above 1", [&](auto&, auto& t) { t[3][0] = 1.25f; }},
      {"a transmittance NaN", [&](auto&, auto& t) { t[3][2] = std::nanf(""); }},
      {"transmittances missing", [&](auto&, auto& t) { t.pop_back(); }}};
  for (const auto& [what, mutate] : hostile) {
    std::vector<TopNode> nodes = built.nodes();
    std::vector<std::array<float, 3>> t = built.transmittance();
    mutate(nodes, t);
    EXPECT_THROW(stored(std::move(nodes), std::move(t)), InputError) << what;
  }
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_THROW(TopTree::fromNodes(built.nodes(), PsvLight::sun({0, inf, 0}), {}, 1, 1), InputError);
  EXPECT_THROW(TopTree::fromNodes(built.nodes(), PsvLight::sun({0, -2, 0}), {}, 1, 1), InputError) << "not a unit direction";
  EXPECT_THROW(TopTree::fromNodes(built.nodes(), sun, {inf, 0, 0}, 1, 1), InputError);
  EXPECT_THROW(TopTree::fromNodes(built.nodes(), sun, {}, 0, 1), InputError);
  EXPECT_THROW(TopTree::fromNodes(built.nodes(), sun, {}, 1, -inf), InputError);
}

// Every triangle below a node's pos (neg) child lies in its closed positive (negative)
/// half-space within the build's tolerance, and its inter child's within the wedge.
void checkSubtree(const TopTree& tree, const Scene& scene, uint32_t i, std::vector<uint32_t>& frusta) {
  if (i == 0) return;
  const auto& nodes = tree.nodes();
  const uint32_t k = (i - 1) / 4;
  if (i % 4 == 1) frusta.push_back(k);
  const TopNode& n = nodes[i];
  ASSERT_TRUE(n.pos == 0 || n.pos > i);
  ASSERT_TRUE(n.inter == 0 || n.inter > i);
  ASSERT_TRUE(n.neg == 0 || n.neg > i);
  if (i % 4 != 0) {
    ASSERT_EQ(n.neg, i + 1) << "a shadow plane's neg is its frustum's next plane";
  }
  if (n.pos) {
    ASSERT_EQ(n.pos % 4, 1u);
  }
  if (n.inter) {
    ASSERT_EQ(n.inter % 4, 1u);
  }
  if (i % 4 == 0 && n.neg) {
    ASSERT_EQ(n.neg % 4, 1u);
  }
  const PsvLight& light = tree.light();
  // Each corner's distance and the build's tolerance for it (doubled: the test's own rounding).
  auto distances = [&](uint32_t frustum, double s[3], double tol[3]) {
    const uint32_t t = tree.triangleOf(frustum);
    for (int c = 0; c < 3; ++c) {
      const Vec3 v = scene.vertex(t, c) - tree.origin();
      s[c] = double(n.plane[0]) * v.x + double(n.plane[1]) * v.y + double(n.plane[2]) * v.z + double(n.plane[3]);
      tol[c] = 2 * (tree.buildTolerance() +
                    (light.directional ? 0 : kTopBuildTolerance * length(scene.vertex(t, c) - light.vector)));
    }
  };
  std::vector<uint32_t> below;
  for (uint32_t child : {n.pos, n.neg}) {
    below.clear();
    checkSubtree(tree, scene, child, below);
    const bool chain = child == n.neg && i % 4 != 0;  // the frustum's own next plane
    for (uint32_t f : below) {
      if (chain) break;
      double s[3], tol[3];
      distances(f, s, tol);
      for (int c = 0; c < 3; ++c) {
        if (child == n.pos) {
          ASSERT_GE(s[c], -tol[c]) << "node " << i << " frustum " << f;
        } else {
          ASSERT_LE(s[c], tol[c]) << "node " << i << " frustum " << f;
        }
      }
    }
    frusta.insert(frusta.end(), below.begin(), below.end());
  }
  below.clear();
  checkSubtree(tree, scene, n.inter, below);
  if (i % 4 != 0 && light.directional)
    for (uint32_t f : below) {
      double s[3], tol[3];
      distances(f, s, tol);
      for (double si : s) ASSERT_LE(std::fabs(si), double(n.wedge)) << "node " << i << " frustum " << f;
    }
  frusta.insert(frusta.end(), below.begin(), below.end());
}

TEST(TopTree, HasTheSeedsStructure) {
  const Scene soup = randomSoup(800, 3);
  for (const PsvLight& light : {PsvLight::sun(normalize(Vec3{0.2, -1, 0.1})), PsvLight::point(Vec3{0.4, 1.5, 0.6})}) {
    const TopTree tree = TopTree::build(soup, light);
    const size_t n = tree.frustumCount();
    EXPECT_EQ(tree.nodes().size(), 4 * n + 1);
    EXPECT_EQ(tree.bytes(), 32 * (4 * n + 1));
    EXPECT_EQ(n + tree.buildStats().degenerate + tree.buildStats().culled, soup.triangleCount());
    std::vector<uint32_t> frusta;
    checkSubtree(tree, soup, tree.root(), frusta);
    std::sort(frusta.begin(), frusta.end());
    ASSERT_EQ(frusta.size(), n) << "every frustum is reached once";
    for (size_t k = 0; k < n; ++k) EXPECT_EQ(frusta[k], k);
  }
}

TEST(TopTree, TheSameSeedGivesTheSameNodesOnAnyThreadCount) {
  const Scene city = makeProceduralCity(4, 3);
  const PsvLight sun = PsvLight::sun(normalize(Vec3{0.3, -1, 0.2}));
  const TopTree many = TopTree::build(city, sun);
  std::vector<TopNode> one;
  {
    tbb::global_control single(tbb::global_control::max_allowed_parallelism, 1);
    one = TopTree::build(city, sun).nodes();
  }
  ASSERT_EQ(one.size(), many.nodes().size());
  EXPECT_EQ(std::memcmp(one.data(), many.nodes().data(), one.size() * sizeof(TopNode)), 0);
  TopTreeOptions other;
  other.seed = 2;
  const TopTree reseeded = TopTree::build(city, sun, other);
  EXPECT_NE(std::memcmp(reseeded.nodes().data(), many.nodes().data(), one.size() * sizeof(TopNode)), 0);
}

TEST(TopTree, AStripInOrderIsQuadraticAndRandomOrderIsNot) {
  // Seed 003 Fig. 4a: slivers side by side, inserted left to right, each in the previous
  // one's positive side: a chain as long as the strip.
  Scene strip;
  const int n = 3000;
  for (int i = 0; i < n; ++i) {
    const uint32_t b = uint32_t(strip.positions.size());
    const double x = i * 1.0;
    strip.positions.insert(strip.positions.end(), {Vec3{x, 0, 0}, Vec3{x + 0.5, 0, 10}, Vec3{x + 0.25, 0, 0}});
    strip.indices.insert(strip.indices.end(), {b, b + 1, b + 2});
  }
  const PsvLight sun = PsvLight::sun(Vec3{0, -1, 0});
  TopTreeOptions inOrder;
  inOrder.randomOrder = false;
  const TopTree chain = TopTree::build(strip, sun, inOrder);
  const TopTree shuffled = TopTree::build(strip, sun);
  EXPECT_GT(chain.buildStats().depth, uint32_t(n / 2));
  EXPECT_LT(shuffled.buildStats().depth, 120u);
  EXPECT_GT(chain.buildStats().classified, 20 * shuffled.buildStats().classified);
  // Both still answer exactly, and the chain's walk overflows a GPU's stack only where it is deep.
  for (double x : {0.15, 1500.15, 2999.15}) {
    EXPECT_TRUE(chain.shadowed(Vec3{x, -1, 1}));
    EXPECT_TRUE(shuffled.shadowed(Vec3{x, -1, 1}));
    EXPECT_FALSE(shuffled.shadowed(Vec3{x + 0.6, -1, 1}));
  }
}

// Randomized insertion is n log n: its work (triangle-plane tests) over n log2 n stays
// flat from a small city to one sixteen times its size, and the tree's depth grows like
// log n.
TEST(TopTree, TheBuildIsNLogN) {
  const PsvLight sun = PsvLight::sun(normalize(Vec3{0.35, -1, 0.25}));
  double first = 0;
  uint32_t firstDepth = 0;
  for (int blocks : {6, 12, 24}) {
    const TopTree tree = TopTree::build(makeProceduralCity(blocks, 1), sun);
    const double n = double(tree.frustumCount());
    const double work = double(tree.buildStats().classified) / (n * std::log2(n));
    if (first == 0) {
      first = work;
      firstDepth = tree.buildStats().depth;
      continue;
    }
    EXPECT_LT(work, 1.3 * first) << blocks << " blocks";
    EXPECT_GT(work, first / 1.3) << blocks << " blocks";
    EXPECT_LT(tree.buildStats().depth, firstDepth + 16) << blocks << " blocks";
  }
}

TEST(TopTree, AgreesWithEmbreeAwayFromShadowBoundaries) {
  const Scene city = makeProceduralCity(3, 4);
  Vec3 lo, hi;
  sceneBounds(city, lo, hi);
  const RayScene rays(city, (lo + hi) * 0.5);
  const double h = length(hi - lo) * 1e-3;
  const Vec3 lamp{lo.x + 0.6 * (hi.x - lo.x), hi.y + 0.1 * (hi.y - lo.y), lo.z + 0.45 * (hi.z - lo.z)};
  for (const PsvLight& light : {PsvLight::sun(normalize(Vec3{0.505259, -0.379456, 0.775066})), PsvLight::point(lamp)}) {
    const TopTree tree = TopTree::build(city, light);
    auto embreeLit = [&](const Vec3& p) {
      if (light.directional) return !rays.occluded(p, -light.vector, 0, 1e6);
      const Vec3 d = light.vector - p;
      return !rays.occluded(p, normalize(d), 0, length(d));
    };
    SplitMix64 rng(9);
    size_t compared = 0, lit = 0, near = 0, disagree = 0;
    for (int i = 0; i < 20000; ++i) {
      const Vec3 p = randomIn(rng, lo, hi);
      if (rays.closedNesting(p, Vec3{0, 1, 0}, 1e6, ClosedMode::Auto) > 0) continue;  // culled back faces' inside
      const bool e = embreeLit(p);
      bool isNear = false;
      for (int a = 0; a < 3 && !isNear; ++a)
        for (double sgn : {-1.0, 1.0}) {
          Vec3 q = p;
          (a == 0 ? q.x : a == 1 ? q.y : q.z) += sgn * h;
          if (embreeLit(q) != e) isNear = true;
        }
      ++compared;
      lit += e;
      near += isNear;
      if (!isNear && tree.shadowed(p) == e) ++disagree;
    }
    EXPECT_GT(compared, 10000u);
    EXPECT_GT(lit, compared / 10);
    EXPECT_LT(lit, compared - compared / 10);
    EXPECT_LT(near, compared / 10);
    EXPECT_EQ(disagree, 0u) << (light.directional ? "sun" : "point light");
  }
}

TEST(TopTree, ALightInsideAClosedMeshShadowsEverythingOutside) {
  Scene box;
  appendBox(box, Vec3{-1, -1, -1}, Vec3{1, 1, 1});
  finalizeScene(box);
  const TopTree tree = TopTree::build(box, PsvLight::point(Vec3{0.1, 0.2, -0.3}));
  EXPECT_EQ(tree.buildStats().culled, 0u) << "every face looks away from a light inside";
  SplitMix64 rng(4);
  for (int i = 0; i < 2000; ++i) {
    const Vec3 p = randomIn(rng, Vec3{-3, -3, -3}, Vec3{3, 3, 3});
    const double m = std::max({std::fabs(p.x), std::fabs(p.y), std::fabs(p.z)});
    if (std::fabs(m - 1) < 1e-3) continue;
    EXPECT_EQ(tree.shadowed(p), m > 1) << p.x << " " << p.y << " " << p.z;
  }
}

TEST(TopTree, FrontFaceCullingHalvesAClosedSceneAndKeepsItsShadows) {
  const Scene city = makeProceduralCity(3, 5);
  const PsvLight sun = PsvLight::sun(normalize(Vec3{0.4, -1, 0.3}));
  TopTreeOptions all;
  all.frontFaceCulling = false;
  const TopTree culled = TopTree::build(city, sun), full = TopTree::build(city, sun, all);
  EXPECT_LT(culled.frustumCount(), full.frustumCount() * 6 / 10);
  Vec3 lo, hi;
  sceneBounds(city, lo, hi);
  const RayScene rays(city, (lo + hi) * 0.5);
  SplitMix64 rng(6);
  size_t differ = 0, compared = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vec3 p = randomIn(rng, lo, hi);
    if (rays.closedNesting(p, Vec3{0, 1, 0}, 1e6, ClosedMode::Auto) > 0) continue;
    ++compared;
    differ += culled.shadowed(p) != full.shadowed(p);
  }
  EXPECT_GT(compared, 10000u);
  EXPECT_LE(differ, compared / 1000) << "outside closed parts only points on surfaces may differ";
}

TEST(TopTree, BadInputIsRefusedAndDegenerateInputCastsNothing) {
  Scene s;
  s.positions = {Vec3{0, 0, 0}, Vec3{1, 0, 0}, Vec3{0, 0, 1}};
  s.indices = {0, 1, 3};
  EXPECT_THROW(TopTree::build(s, PsvLight::sun(Vec3{0, -1, 0})), InputError);
  s.indices = {0, 1, 2};
  EXPECT_THROW(TopTree::build(s, PsvLight::sun(Vec3{0, 0, 0})), InputError);
  EXPECT_THROW(TopTree::build(s, PsvLight::point(Vec3{std::nan(""), 0, 0})), InputError);
  s.closed = {1, 1};
  EXPECT_THROW(TopTree::build(s, PsvLight::sun(Vec3{0, -1, 0})), InputError);
  s.closed.clear();

  // Zero area, a NaN corner, edge-on to the sun: no frustum, no shadow, no crash.
  Scene bad;
  bad.positions = {Vec3{0, 1, 0}, Vec3{1, 1, 0}, Vec3{2, 1, 0}, Vec3{std::nan(""), 1, 0}, Vec3{0, 1, 1},
                   Vec3{0, 2, 0}};
  bad.indices = {0, 1, 2, 0, 3, 4, 0, 1, 4};
  const TopTree none = TopTree::build(bad, PsvLight::sun(Vec3{0, 0, 1}));
  EXPECT_EQ(none.frustumCount(), 0u);
  EXPECT_EQ(none.buildStats().degenerate, 3u);
  EXPECT_FALSE(none.shadowed(Vec3{0.2, 1.2, 5}));
  EXPECT_FALSE(none.shadowed(Vec3{std::nan(""), 0, 0}));

  // A stack too small overflows and says so.
  const Scene soup = randomSoup(400, 1);
  const TopTree tree = TopTree::build(soup, PsvLight::sun(Vec3{0, -1, 0}));
  size_t overflows = 0;
  SplitMix64 rng(2);
  for (int i = 0; i < 200; ++i) {
    const Vec3 p = randomIn(rng, Vec3{0, 0, 0}, Vec3{1, 1, 1});
    const TopAnswer a = tree.query(p, 2);
    overflows += a == TopAnswer::Overflow;
    if (a != TopAnswer::Overflow) {
      EXPECT_EQ(a == TopAnswer::Shadowed, tree.inAnyFrustum(p));
    }
  }
  EXPECT_GT(overflows, 0u);
}

}  // namespace
}  // namespace cpvs
