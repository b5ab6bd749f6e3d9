#include "cpvs/raytrace/exact_caster.h"

#include <algorithm>
#include <numeric>

namespace cpvs {

namespace {

constexpr uint32_t kLeafTriangles = 4;
constexpr uint32_t kBins = 16;
// Below this depth nodes split at the median: at most 32 more levels for 2^32 triangles,
// within the walk's stack of 128.
constexpr int kMaxSahDepth = 64;
// pbrt's gamma(3): the relative error of a slab's far distance; widening it by that keeps
// the box test from cutting off a hit the triangle test finds.
constexpr double kFarWiden = 1 + 2 * (3 * 0x1p-53) / (1 - 3 * 0x1p-53);

}  // namespace

ExactCaster::ExactCaster(const Scene& scene) {
  const size_t n = scene.triangleCount();
  triangles_.resize(n);
  std::vector<Vec3> centroids(n);
  for (size_t t = 0; t < n; ++t) {
    const Vec3 a = scene.vertex(t, 0), b = scene.vertex(t, 1), c = scene.vertex(t, 2);
    triangles_[t] = {a, b - a, c - a};
    centroids[t] = Vec3{a.x + b.x + c.x, a.y + b.y + c.y, a.z + b.z + c.z};  // x3: only order matters
  }
  order_.resize(n);
  std::iota(order_.begin(), order_.end(), 0u);
  nodes_.reserve(2 * n);
  if (n) build(0, uint32_t(n), centroids, 0);
}

uint32_t ExactCaster::build(uint32_t begin, uint32_t end, std::vector<Vec3>& centroids, int depth) {
  const uint32_t index = uint32_t(nodes_.size());
  nodes_.push_back({});
  Node node{};
  for (int k = 0; k < 3; ++k) node.lo[k] = std::numeric_limits<double>::infinity(), node.hi[k] = -node.lo[k];
  double cLo[3] = {node.lo[0], node.lo[1], node.lo[2]}, cHi[3] = {node.hi[0], node.hi[1], node.hi[2]};
  for (uint32_t i = begin; i < end; ++i) {
    const Triangle& tr = triangles_[order_[i]];
    const Vec3 v[3] = {tr.a, tr.a + tr.e1, tr.a + tr.e2};
    for (const Vec3& p : v)
      for (int k = 0; k < 3; ++k) node.lo[k] = std::min(node.lo[k], p[k]), node.hi[k] = std::max(node.hi[k], p[k]);
    for (int k = 0; k < 3; ++k) {
      const double c = centroids[order_[i]][k];
      cLo[k] = std::min(cLo[k], c), cHi[k] = std::max(cHi[k], c);
    }
  }
  // The vertices are a + e rounded, not the scene's own: widen by their rounding.
  for (int k = 0; k < 3; ++k) {
    const double pad = 0x1p-50 * std::max(std::fabs(node.lo[k]), std::fabs(node.hi[k]));
    node.lo[k] -= pad, node.hi[k] += pad;
  }
  if (end - begin <= kLeafTriangles) {
    node.first = begin, node.count = end - begin;
    nodes_[index] = node;
    return index;
  }
  // Binned surface area heuristic over the centroids: the split plane of least expected
  // cost, ties to the lowest axis and plane; a stable partition keeps the order a pure
  // function of the scene. Centroids that do not split, and nodes below kMaxSahDepth
  // (which keeps the walk's stack bounded), take the median along the widest axis.
  struct Bin {
    double lo[3], hi[3];
    uint32_t count;
  };
  auto area = [](const double* lo, const double* hi) {
    const double x = hi[0] - lo[0], y = hi[1] - lo[1], z = hi[2] - lo[2];
    return x * y + y * z + z * x;
  };
  auto binOf = [&](double c, int k) {
    const double scale = kBins / (cHi[k] - cLo[k]);
    return std::min<uint32_t>(kBins - 1, uint32_t((c - cLo[k]) * scale));
  };
  int axis = -1;
  uint32_t plane = 0;
  double bestCost = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3 && depth < kMaxSahDepth; ++k) {
    if (!(cHi[k] > cLo[k]) || !std::isfinite(kBins / (cHi[k] - cLo[k]))) continue;  // a subnormal extent too
    Bin bins[kBins];
    for (Bin& b : bins) {
      b.count = 0;
      for (int j = 0; j < 3; ++j) b.lo[j] = std::numeric_limits<double>::infinity(), b.hi[j] = -b.lo[j];
    }
    for (uint32_t i = begin; i < end; ++i) {
      Bin& b = bins[binOf(centroids[order_[i]][k], k)];
      ++b.count;
      const Triangle& tr = triangles_[order_[i]];
      for (const Vec3& p : {tr.a, tr.a + tr.e1, tr.a + tr.e2})
        for (int j = 0; j < 3; ++j) b.lo[j] = std::min(b.lo[j], p[j]), b.hi[j] = std::max(b.hi[j], p[j]);
    }
    // Costs of the planes after bin 0 .. kBins - 2: left areas swept up, right ones down.
    double rightCost[kBins];
    Bin acc{};
    for (int j = 0; j < 3; ++j) acc.lo[j] = std::numeric_limits<double>::infinity(), acc.hi[j] = -acc.lo[j];
    for (uint32_t b = kBins - 1; b > 0; --b) {
      acc.count += bins[b].count;
      for (int j = 0; j < 3; ++j) acc.lo[j] = std::min(acc.lo[j], bins[b].lo[j]), acc.hi[j] = std::max(acc.hi[j], bins[b].hi[j]);
      rightCost[b - 1] = acc.count ? area(acc.lo, acc.hi) * acc.count : 0;
    }
    acc.count = 0;
    for (int j = 0; j < 3; ++j) acc.lo[j] = std::numeric_limits<double>::infinity(), acc.hi[j] = -acc.lo[j];
    for (uint32_t b = 0; b + 1 < kBins; ++b) {
      acc.count += bins[b].count;
      for (int j = 0; j < 3; ++j) acc.lo[j] = std::min(acc.lo[j], bins[b].lo[j]), acc.hi[j] = std::max(acc.hi[j], bins[b].hi[j]);
      if (acc.count == 0 || acc.count == end - begin) continue;
      const double cost = area(acc.lo, acc.hi) * acc.count + rightCost[b];
      if (cost < bestCost) bestCost = cost, axis = k, plane = b;
    }
  }
  uint32_t mid;
  if (axis >= 0) {
    mid = uint32_t(std::stable_partition(order_.begin() + begin, order_.begin() + end,
                                         [&](uint32_t t) { return binOf(centroids[t][axis], axis) <= plane; }) -
                   order_.begin());
  } else {
    axis = 0;
    for (int k = 1; k < 3; ++k)
      if (cHi[k] - cLo[k] > cHi[axis] - cLo[axis]) axis = k;
    mid = begin + (end - begin) / 2;
    std::sort(order_.begin() + begin, order_.begin() + end, [&](uint32_t p, uint32_t q) {
      const double cp = centroids[p][axis], cq = centroids[q][axis];
      return cp < cq || (cp == cq && p < q);
    });
  }
  node.axis = uint32_t(axis);
  node.count = 0;
  build(begin, mid, centroids, depth + 1);
  node.first = build(mid, end, centroids, depth + 1);
  nodes_[index] = node;
  return index;
}

bool ExactCaster::intersect(uint32_t t, const Vec3& o, const Vec3& d, double tMax, Hit& best) const {
  const Triangle& tr = triangles_[t];
  const Vec3 p = cross(d, tr.e2);
  const double det = dot(tr.e1, p);
  if (det == 0 || !std::isfinite(det)) return false;
  const double inv = 1 / det;
  const Vec3 s = o - tr.a;
  const double u = dot(s, p) * inv;
  if (!(u >= 0 && u <= 1)) return false;
  const Vec3 q = cross(s, tr.e1);
  const double v = dot(d, q) * inv;
  if (!(v >= 0 && u + v <= 1)) return false;
  const double hitT = dot(tr.e2, q) * inv;
  if (!(hitT > 0 && hitT <= tMax)) return false;
  if (best.triangle != kNoHit && (hitT > best.t || (hitT == best.t && t > best.triangle))) return false;
  best = {t, hitT, det > 0};
  return true;
}

ExactCaster::Hit ExactCaster::firstHit(const Vec3& o, const Vec3& d, double tMax) const {
  Hit best;
  if (nodes_.empty()) return best;
  double inv[3];
  for (int k = 0; k < 3; ++k) inv[k] = d[k] != 0 ? 1 / d[k] : 0;
  // Whether the ray meets a node's box before the best hit so far (or tMax).
  auto enter = [&](const Node& n) {
    double t0 = 0, t1 = (best.triangle != kNoHit ? best.t : tMax) * kFarWiden;
    for (int k = 0; k < 3; ++k) {
      if (d[k] == 0) {
        if (o[k] < n.lo[k] || o[k] > n.hi[k]) return false;
        continue;
      }
      double a = (n.lo[k] - o[k]) * inv[k], b = (n.hi[k] - o[k]) * inv[k];
      if (a > b) std::swap(a, b);
      t0 = std::max(t0, a);
      t1 = std::min(t1, b * kFarWiden);
      if (t0 > t1) return false;
    }
    return true;
  };
  uint32_t stack[128];
  int top = 0;
  if (!enter(nodes_[0])) return best;
  stack[top++] = 0;
  while (top) {
    const Node& n = nodes_[stack[--top]];
    if (n.count) {
      for (uint32_t i = n.first; i < n.first + n.count; ++i) intersect(order_[i], o, d, tMax, best);
      continue;
    }
    const uint32_t self = uint32_t(&n - nodes_.data());
    uint32_t nearChild = self + 1, farChild = n.first;
    if (d[int(n.axis)] < 0) std::swap(nearChild, farChild);
    // The far child goes down first onto the stack so that the near one is walked first.
    if (enter(nodes_[farChild])) stack[top++] = farChild;
    if (enter(nodes_[nearChild])) stack[top++] = nearChild;
  }
  return best;
}

ExactCaster::Hit ExactCaster::firstHitBruteForce(const Vec3& o, const Vec3& d, double tMax) const {
  Hit best;
  for (uint32_t t = 0; t < triangles_.size(); ++t) intersect(t, o, d, tMax, best);
  return best;
}

}  // namespace cpvs
