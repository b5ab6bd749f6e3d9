#include "cpvs/psv/top_tree.h"

#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <string>

#include "cpvs/base/error.h"
#include "cpvs/base/split_mix64.h"

// Compiled with -ffp-contract=off: a distance is the same float on every machine and on a
// GPU that evaluates it with NoContraction.

namespace cpvs {
namespace {

/// A triangle kept for the tree: its corners relative to the origin, its four planes
/// (shadow planes 0..2, capping plane 3), and for a point light its distance from it.
struct Caster {
  Vec3 v[3];
  float plane[4][4];
  double lightDistance = 0;
  uint32_t triangle = 0;
};

void setPlane(float out[4], const Vec3& n, double w) {
  out[0] = float(n.x);
  out[1] = float(n.y);
  out[2] = float(n.z);
  out[3] = float(w);
}

double planeDistance(const float plane[4], const Vec3& p) {
  return double(plane[0]) * p.x + double(plane[1]) * p.y + double(plane[2]) * p.z + double(plane[3]);
}

/// The distance from p to the triangle abc (Ericson, Real-Time Collision Detection 5.1.5).
double distanceToTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return length(ap);
  const Vec3 bp = p - b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return length(bp);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return length(p - (a + ab * (d1 / (d1 - d3))));
  const Vec3 cp = p - c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return length(cp);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return length(p - (a + ac * (d2 / (d2 - d6))));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return length(p - (b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))));
  const double denom = 1 / (va + vb + vc);
  return length(p - (a + ab * (vb * denom) + ac * (vc * denom)));
}

// Below this cosine between the triangle's normal and the light, a triangle is edge-on:
// its shadow is thinner than a float can place.
constexpr double kEdgeOnCosine = 1e-9;

/// What the build shares between its tasks.
struct Builder {
  const std::vector<Caster>& casters;  // by rank
  std::vector<TopNode>& nodes;
  bool directional;
  Vec3 lightRel;  // a point light relative to the origin
  double tolerance;  // absolute; for a point light also this fraction of a vertex's distance to it
  double relTolerance;
  std::atomic<uint64_t> classified{0};
  std::atomic<uint32_t> depth{0};
  tbb::task_group tasks;

  Builder(const std::vector<Caster>& c, std::vector<TopNode>& n, bool dir, const Vec3& light, double tol, double rel)
      : casters(c), nodes(n), directional(dir), lightRel(light), tolerance(tol), relTolerance(rel) {}

  /// +1: t's corners are on or above plane `j` of caster r, one strictly; -1 likewise
  /// below; 0: corners strictly on both sides, or all on it. `wedge` gets t's bound about
  /// the plane when it crosses.
  int classify(const Caster& r, int j, const Caster& t, double& wedge) const {
    bool above = false, below = false;
    double s[3], farthest = 0;
    for (int i = 0; i < 3; ++i) {
      s[i] = planeDistance(r.plane[j], t.v[i]);
      double tol = tolerance;
      if (!directional) tol += relTolerance * length(t.v[i] - lightRel);
      above |= s[i] > tol;
      below |= s[i] < -tol;
    }
    if (above != below) return above ? 1 : -1;
    if (directional) {
      for (double si : s) farthest = std::max(farthest, std::fabs(si));
      wedge = farthest;
    } else {
      // The plane passes the light up to its rounding: distances grow from the light's
      // own, and over the frustum no faster than the corners' over the triangle's distance.
      const double atLight = planeDistance(r.plane[j], lightRel);
      for (double si : s) farthest = std::max(farthest, std::fabs(si - atLight));
      wedge = std::min(1.0, farthest / t.lightDistance);
    }
    return 0;
  }

  /// Places the frustum of the list's first caster in `slot` and the rest below it.
  /// Lists are in rank order, so the nodes are those of inserting by rank one at a time.
  void place(std::vector<uint32_t> list, uint32_t* slot, uint32_t level) {
    struct Work {
      std::vector<uint32_t> list;
      uint32_t* slot;
      uint32_t level;
    };
    std::vector<Work> local;
    local.push_back({std::move(list), slot, level});
    while (!local.empty()) {
      Work w = std::move(local.back());
      local.pop_back();
      const uint32_t r = w.list[0];
      const uint32_t base = 4 * r + 1;
      *w.slot = base;
      uint32_t seen = depth.load(std::memory_order_relaxed);
      while (w.level + 1 > seen && !depth.compare_exchange_weak(seen, w.level + 1)) {
      }
      const Caster& frustum = casters[r];
      // pos of planes 0..3, inter of planes 0..3, neg of plane 3.
      std::vector<uint32_t> pos[4], inter[4], neg;
      double wedge[3] = {0, 0, 0};
      uint64_t tests = 0;
      for (size_t k = 1; k < w.list.size(); ++k) {
        const uint32_t t = w.list[k];
        for (int j = 0; j < 4; ++j) {
          double bound = 0;
          ++tests;
          const int c = classify(frustum, j, casters[t], bound);
          if (c > 0) {
            pos[j].push_back(t);
            break;
          }
          if (c == 0) {
            inter[j].push_back(t);
            if (j < 3) wedge[j] = std::max(wedge[j], bound);
            break;
          }
          if (j == 3) neg.push_back(t);
        }
      }
      classified += tests;
      for (int j = 0; j < 3; ++j)
        // Rounded up, so that the float still bounds every frustum below.
        nodes[base + j].wedge = inter[j].empty() ? 0.0f : std::nextafter(float(wedge[j]), INFINITY);
      auto descend = [&](std::vector<uint32_t>& l, uint32_t* s) {
        if (l.empty()) return;
        if (l.size() >= 4096) {
          // task_group runs const functors: the list travels in a shared vector.
          auto shared = std::make_shared<std::vector<uint32_t>>(std::move(l));
          tasks.run([this, shared, s, lv = w.level + 1] { place(std::move(*shared), s, lv); });
        } else {
          local.push_back({std::move(l), s, w.level + 1});
        }
      };
      for (int j = 0; j < 4; ++j) {
        descend(pos[j], &nodes[base + j].pos);
        descend(inter[j], &nodes[base + j].inter);
      }
      descend(neg, &nodes[base + 3].neg);
    }
  }
};

}  // namespace

float TopTree::distance(const TopNode& n, const float p[3]) {
  return ((n.plane[0] * p[0] + n.plane[1] * p[1]) + n.plane[2] * p[2]) + n.plane[3];
}

void TopTree::relative(const Vec3& p, float out[3]) const {
  out[0] = float(p.x - origin_.x);
  out[1] = float(p.y - origin_.y);
  out[2] = float(p.z - origin_.z);
}

TopTree TopTree::build(const Scene& scene, const PsvLight& light, const TopTreeOptions& options) {
  return build(scene.positions, scene.indices, scene.closed, light, options);
}

TopTree TopTree::build(const std::vector<Vec3>& positions, const std::vector<uint32_t>& indices,
                       const std::vector<uint8_t>& closed, const PsvLight& light, const TopTreeOptions& options) {
  TopTree tree = frusta(positions, indices, closed, light, options);
  tree.link();
  return tree;
}

TopTree TopTree::frusta(const std::vector<Vec3>& positions, const std::vector<uint32_t>& indices,
                        const std::vector<uint8_t>& closed, const PsvLight& light, const TopTreeOptions& options) {
  if (indices.size() % 3 != 0) throw InputError("shadow volumes: the index count is not a multiple of 3");
  const size_t n = indices.size() / 3;
  if (!closed.empty() && closed.size() != n)
    throw InputError("shadow volumes: " + std::to_string(closed.size()) + " closed flags for " + std::to_string(n) +
                     " triangles");
  for (uint32_t i : indices)
    if (i >= positions.size())
      throw InputError("shadow volumes: index " + std::to_string(i) + " is past the " +
                       std::to_string(positions.size()) + " positions");
  if (!isFinite(light.vector)) throw InputError("shadow volumes: the light's position or direction is not finite");
  if (light.directional && !(length(light.vector) > 0))
    throw InputError("shadow volumes: the sun's direction is zero");
  if (n >= (uint64_t(1) << 29)) throw InputError("shadow volumes: more than 2^29 triangles");

  TopTree tree;
  tree.light_ = light;
  if (light.directional) tree.light_.vector = normalize(light.vector);
  const Vec3 d = tree.light_.vector;
  tree.stats_.triangles = n;

  // The domain: where queries are, or the casters (and a point light).
  Vec3 lo = options.domainLo, hi = options.domainHi;
  if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z)) {
    const double inf = std::numeric_limits<double>::infinity();
    lo = {inf, inf, inf};
    hi = -lo;
    for (uint32_t i : indices)
      if (isFinite(positions[i])) {
        lo = min(lo, positions[i]);
        hi = max(hi, positions[i]);
      }
    if (!light.directional) {
      lo = min(lo, light.vector);
      hi = max(hi, light.vector);
    }
    if (!(lo.x <= hi.x)) lo = hi = Vec3{};
  }
  if (!isFinite(lo) || !isFinite(hi)) throw InputError("shadow volumes: the query domain is not finite");
  tree.origin_ = (lo + hi) * 0.5;
  const double extent = std::max(length(hi - lo) * 0.5, 1e-30);
  tree.buildTolerance_ = kTopBuildTolerance * extent;
  tree.queryMargin_ = kTopQueryMargin * extent;
  const Vec3 lightRel = light.directional ? Vec3{} : light.vector - tree.origin_;
  tree.relative(light.vector, tree.lightRel_);

  // Each triangle's frustum, or why it has none.
  std::vector<Caster> all(n);
  std::vector<uint8_t> kind(n);  // 0 kept, 1 degenerate, 2 culled
  tbb::parallel_for(size_t(0), n, [&](size_t t) {
    Caster& c = all[t];
    c.triangle = uint32_t(t);
    for (int i = 0; i < 3; ++i) c.v[i] = positions[indices[3 * t + i]] - tree.origin_;
    const Vec3 normal = cross(c.v[1] - c.v[0], c.v[2] - c.v[0]);
    const double area2 = length(normal);
    if (!isFinite(c.v[0]) || !isFinite(c.v[1]) || !isFinite(c.v[2]) || !(area2 > 0) || !std::isfinite(area2)) {
      kind[t] = 1;
      return;
    }
    // facing > 0: the triangle's front faces away from the light (it is back-facing).
    const double facing = light.directional ? dot(normal, d) : dot(c.v[0] - lightRel, normal);
    const double scale = light.directional ? area2 : area2 * length(c.v[0] - lightRel);
    if (!(std::fabs(facing) > kEdgeOnCosine * scale)) {
      kind[t] = 1;
      return;
    }
    if (facing < 0 && options.frontFaceCulling && !closed.empty() && closed[t]) {
      kind[t] = 2;
      return;
    }
    const double sign = facing > 0 ? 1 : -1;
    for (int j = 0; j < 3; ++j) {
      const Vec3& a = c.v[j];
      const Vec3& b = c.v[(j + 1) % 3];
      // Oriented so the third corner is inside (negative): see the sign derivation of the
      // determinant, the same for all three edges.
      const Vec3 m = light.directional ? cross(b - a, d) * sign : cross(b - lightRel, a - lightRel) * sign;
      const Vec3 u = normalize(m);
      setPlane(c.plane[j], u, -dot(u, light.directional ? a : lightRel));
    }
    const Vec3 cap = normal * (-sign / area2);  // the light on its positive side
    setPlane(c.plane[3], cap, -dot(cap, c.v[0]));
    if (!light.directional) c.lightDistance = distanceToTriangle(lightRel, c.v[0], c.v[1], c.v[2]);
    kind[t] = 0;
  });
  std::vector<uint32_t> kept;
  for (size_t t = 0; t < n; ++t) {
    if (kind[t] == 0) kept.push_back(uint32_t(t));
    tree.stats_.degenerate += kind[t] == 1;
    tree.stats_.culled += kind[t] == 2;
  }
  // The insertion order: Fisher-Yates with the project's generator (the same everywhere).
  if (options.randomOrder) {
    SplitMix64 rng(options.seed);
    for (size_t i = kept.size(); i > 1; --i) std::swap(kept[i - 1], kept[rng.next() % i]);
  }
  const size_t frusta = kept.size();
  tree.stats_.frusta = frusta;
  std::vector<Caster> byRank(frusta);
  tree.triangleOf_.resize(frusta);
  for (size_t r = 0; r < frusta; ++r) {
    byRank[r] = all[kept[r]];
    tree.triangleOf_[r] = kept[r];
  }
  all.clear();
  all.shrink_to_fit();

  tree.nodes_.assign(4 * frusta + 1, TopNode{{0, 0, 0, 0}, 0, 0, 0, 0});
  tree.corners_.resize(kTopCornerDoubles * frusta);
  for (size_t r = 0; r < frusta; ++r) {
    for (int j = 0; j < 4; ++j) {
      TopNode& node = tree.nodes_[4 * r + 1 + j];
      std::copy(byRank[r].plane[j], byRank[r].plane[j] + 4, node.plane);
      if (j < 3) node.neg = uint32_t(4 * r + 2 + j);
    }
    double* c = &tree.corners_[kTopCornerDoubles * r];
    for (int i = 0; i < 3; ++i) c[3 * i] = byRank[r].v[i].x, c[3 * i + 1] = byRank[r].v[i].y, c[3 * i + 2] = byRank[r].v[i].z;
    c[9] = byRank[r].lightDistance;
  }
  tree.wedges_ = options.wedges;
  tree.linked_ = frusta == 0;
  return tree;
}

TopTree TopTree::fromNodes(std::vector<TopNode> nodes, const PsvLight& light, const Vec3& origin, double buildTolerance,
                           double queryMargin, std::vector<std::array<float, 3>> transmittance) {
  auto fail = [](const std::string& why) { throw InputError("shadow volumes: " + why); };
  if (nodes.empty() || (nodes.size() - 1) % 4 != 0 || nodes.size() > (uint64_t(1) << 31))
    fail(std::to_string(nodes.size()) + " nodes, not 4 per frustum and the leaf");
  if (!isFinite(light.vector) || (light.directional && std::fabs(length(light.vector) - 1) > 1e-9))
    fail("the light's position or direction is not finite (or not a unit direction)");
  if (!isFinite(origin)) fail("the origin is not finite");
  if (!(buildTolerance > 0 && std::isfinite(buildTolerance) && queryMargin > 0 && std::isfinite(queryMargin)))
    fail("the margins are not positive and finite");
  const uint64_t size = nodes.size();
  const TopNode& leaf = nodes[0];
  if (leaf.pos != 0 || leaf.inter != 0 || leaf.neg != 0) fail("the leaf has children");
  // Every frustum's first plane (4k + 1) but the root's is the child of exactly one node,
  // and only of an earlier one: then a walk meets each node at most once.
  std::vector<uint8_t> parents(size, 0);
  auto child = [&](uint64_t i, uint32_t c) {
    if (c == 0) return;
    if (c % 4 != 1 || c <= i || c >= size) fail("node " + std::to_string(i) + " has child " + std::to_string(c) + ", not a later frustum");
    if (parents[c]++ != 0) fail("frustum node " + std::to_string(c) + " has two parents");
  };
  for (uint64_t i = 1; i < size; ++i) {
    const TopNode& n = nodes[i];
    for (float f : n.plane)
      if (!std::isfinite(f)) fail("node " + std::to_string(i) + "'s plane is not finite");
    child(i, n.pos);
    child(i, n.inter);
    if (i % 4 != 0) {
      if (n.neg != i + 1) fail("node " + std::to_string(i) + "'s neg child is not its frustum's next plane");
      if (!(n.wedge >= 0)) fail("node " + std::to_string(i) + "'s wedge is negative");
    } else {
      child(i, n.neg);
    }
  }
  for (uint64_t k = 5; k < size; k += 4)
    if (parents[k] != 1) fail("frustum node " + std::to_string(k) + " hangs nowhere");
  const size_t frusta = (size - 1) / 4;
  if (!transmittance.empty()) {
    if (transmittance.size() != frusta)
      fail(std::to_string(transmittance.size()) + " transmittances for " + std::to_string(frusta) + " frusta");
    for (const auto& t : transmittance)
      for (float c : t)
        if (!(c >= 0 && c <= 1) || (c > 0 && c < kMinTransmittance)) fail("a transmittance outside [0, 1] or subnormal");
  }
  if (!(float(queryMargin) >= std::numeric_limits<float>::min()))
    fail("the query margin is subnormal in float");
  TopTree tree;
  tree.nodes_ = std::move(nodes);
  tree.light_ = light;
  tree.origin_ = origin;
  tree.relative(light.vector, tree.lightRel_);
  tree.buildTolerance_ = buildTolerance;
  tree.queryMargin_ = queryMargin;
  tree.transmittance_ = std::move(transmittance);
  tree.triangleOf_.resize(frusta);
  for (size_t k = 0; k < frusta; ++k) tree.triangleOf_[k] = uint32_t(k);
  tree.stats_.triangles = tree.stats_.frusta = frusta;
  return tree;
}

void TopTree::link() {
  if (linked_) return;
  const size_t frusta = frustumCount();
  std::vector<Caster> byRank(frusta);
  for (size_t r = 0; r < frusta; ++r) {
    Caster& c = byRank[r];
    const double* k = &corners_[kTopCornerDoubles * r];
    for (int i = 0; i < 3; ++i) c.v[i] = Vec3{k[3 * i], k[3 * i + 1], k[3 * i + 2]};
    c.lightDistance = k[9];
    for (int j = 0; j < 4; ++j) std::copy(nodes_[4 * r + 1 + j].plane, nodes_[4 * r + 1 + j].plane + 4, c.plane[j]);
  }
  const Vec3 lightRel = light_.directional ? Vec3{} : light_.vector - origin_;
  Builder b{byRank, nodes_, light_.directional, lightRel, buildTolerance_, light_.directional ? 0.0 : kTopBuildTolerance};
  std::vector<uint32_t> ranks(frusta);
  for (size_t r = 0; r < frusta; ++r) ranks[r] = uint32_t(r);
  uint32_t root = 0;
  b.tasks.run([&b, &ranks, &root] { b.place(std::move(ranks), &root, 0); });
  b.tasks.wait();
  CPVS_CHECK(root == 1);
  stats_.classified = b.classified;
  stats_.depth = b.depth;
  // Without the wedge test every inter child is walked: a bound no point exceeds (a sine
  // of 1 for a point light, whose distances never exceed their distance to the light).
  if (!wedges_)
    for (size_t i = 1; i < nodes_.size(); ++i)
      if (i % 4 != 0) nodes_[i].wedge = light_.directional ? std::numeric_limits<float>::infinity() : 1.0f;
  corners_.clear();
  corners_.shrink_to_fit();
  linked_ = true;
}

template <class Inside>
TopAnswer TopTree::walk(const Vec3& p, uint32_t stackLimit, TopQueryStats* stats, Inside&& inside) const {
  CPVS_CHECK(linked_);
  TopQueryStats local;
  TopQueryStats& st = stats ? *stats : local;
  st = {};
  if (root() == 0) return TopAnswer::Lit;
  float x[3];
  relative(p, x);
  const bool directional = light_.directional;
  float r = 0;
  if (!directional) {
    const float dx = x[0] - lightRel_[0], dy = x[1] - lightRel_[1], dz = x[2] - lightRel_[2];
    r = std::sqrt((dx * dx + dy * dy) + dz * dz);
  }
  const float margin = float(queryMargin_) + float(kTopQueryMargin) * r;
  // An entry is a node and, on a frustum's chain of planes, whether p is already known to
  // be outside one of its earlier planes (bit 31).
  constexpr uint32_t kOutside = 0x80000000u;
  constexpr uint32_t kLocal = 64;
  uint32_t fixed[kLocal];
  std::vector<uint32_t> grown;
  uint32_t* stack = fixed;
  uint32_t capacity = std::min(stackLimit, kLocal);
  uint32_t top = 0;
  auto push = [&](uint32_t entry) {
    if ((entry & ~kOutside) == 0) return true;
    if (top == capacity) {
      if (capacity >= stackLimit) return false;
      if (grown.empty()) grown.assign(fixed, fixed + top);
      capacity = std::min<uint64_t>(stackLimit, uint64_t(capacity) * 2);
      grown.resize(capacity);
      stack = grown.data();
    }
    stack[top++] = entry;
    st.maxStack = std::max(st.maxStack, top);
    return true;
  };
  if (!push(root())) return TopAnswer::Overflow;
  while (top > 0) {
    const uint32_t entry = stack[--top];
    const uint32_t i = entry & ~kOutside;
    const TopNode& node = nodes_[i];
    ++st.visited;
    const float s = distance(node, x);
    if (i % 4 != 0) {
      const bool outside = (i % 4 != 1) && (entry & kOutside);  // a frustum's first plane starts afresh
      bool ok = true;
      if (s > -margin) ok &= push(node.pos);
      if (s < margin) ok &= push(node.neg | ((outside || !(s < 0)) ? kOutside : 0));
      const float bound = directional ? node.wedge + margin : margin + node.wedge * r;
      if (std::fabs(s) <= bound) ok &= push(node.inter);
      if (!ok) return TopAnswer::Overflow;
    } else {
      // p is in frustum i / 4 - 1: the shadow query stops there, the transmittance goes on.
      if (!(entry & kOutside) && s < 0 && inside(i / 4 - 1)) return TopAnswer::Shadowed;
      bool ok = true;
      if (s < margin) ok &= push(node.neg);
      ok &= push(node.inter);
      ok &= push(node.pos);
      if (!ok) return TopAnswer::Overflow;
    }
  }
  return TopAnswer::Lit;
}

TopAnswer TopTree::query(const Vec3& p, uint32_t stackLimit, TopQueryStats* stats) const {
  return walk(p, stackLimit, stats, [](uint32_t) { return true; });
}

void TopTree::setTransmittance(const std::vector<std::array<float, 3>>& perTriangle) {
  if (perTriangle.size() != stats_.triangles)
    throw InputError("shadow volumes: " + std::to_string(perTriangle.size()) + " transmittances for " +
                     std::to_string(stats_.triangles) + " triangles");
  for (const auto& t : perTriangle)
    for (float c : t)
      if (!(c >= 0 && c <= 1) || (c > 0 && c < kMinTransmittance))
        throw InputError("shadow volumes: a transmittance outside [0, 1] or subnormal");
  transmittance_.resize(frustumCount());
  for (size_t k = 0; k < frustumCount(); ++k) transmittance_[k] = perTriangle[triangleOf_[k]];
}

TopAnswer TopTree::transmittanceAt(const Vec3& p, uint32_t stackLimit, std::array<float, 3>& out,
                                   TopQueryStats* stats) const {
  CPVS_CHECK(transmittance_.size() == frustumCount());
  out = {1, 1, 1};
  return walk(p, stackLimit, stats, [&](uint32_t k) {
    // A product below the least normal float is 0, as a device that flushes it makes it.
    for (int c = 0; c < 3; ++c) {
      out[c] *= transmittance_[k][c];
      if (out[c] < kMinTransmittance) out[c] = 0;
    }
    return false;
  });
}

std::array<float, 3> TopTree::transmittanceAt(const Vec3& p) const {
  std::array<float, 3> t;
  transmittanceAt(p, std::numeric_limits<uint32_t>::max(), t);
  return t;
}

bool TopTree::shadowed(const Vec3& p) const {
  return query(p, std::numeric_limits<uint32_t>::max()) == TopAnswer::Shadowed;
}

bool TopTree::holds(size_t k, const float x[3]) const {
  for (int j = 0; j < 4; ++j)
    if (!(distance(nodes_[4 * k + 1 + j], x) < 0)) return false;
  return true;
}

std::vector<uint32_t> TopTree::frustaHolding(const Vec3& p) const {
  float x[3];
  relative(p, x);
  std::vector<uint32_t> out;
  for (size_t k = 0; k < frustumCount(); ++k)
    if (holds(k, x)) out.push_back(uint32_t(k));
  return out;
}

bool TopTree::inAnyFrustum(const Vec3& p) const {
  float x[3];
  relative(p, x);
  for (size_t k = 0; k < frustumCount(); ++k)
    if (holds(k, x)) return true;
  return false;
}

}  // namespace cpvs
