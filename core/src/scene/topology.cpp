// Scene topology: zero-area triangle removal, closed-part classification, content hash
// and bounds. The closedness rules are the ones used to measure shared/scenes/README.md:
// vertices welded by exact position, a part is an edge-connected component, and a part
// is closed when every undirected edge in it is used by exactly two triangles, once in
// each direction, and its signed volume is positive (outward-facing).
#include <algorithm>
#include <bit>
#include <cstring>
#include <numeric>
#include <string>
#include <unordered_map>
#include <vector>

#include <xxhash.h>

#include "cpvs/scene/scene.h"
#include "cpvs/base/text.h"
#include "cpvs/base/vec3.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/error.h"

namespace cpvs {
namespace {

/// Bit patterns of a position, the key of the exact-position weld. -0.0 is folded into
/// +0.0 first: the two compare equal, so they are the same point.
struct PositionKey {
  uint64_t b[3];
  bool operator==(const PositionKey&) const = default;
};

PositionKey keyOf(const Vec3& p) {
  return {{std::bit_cast<uint64_t>(p.x + 0.0), std::bit_cast<uint64_t>(p.y + 0.0),
           std::bit_cast<uint64_t>(p.z + 0.0)}};
}

struct PositionKeyHash {
  size_t operator()(const PositionKey& k) const { return XXH3_64bits(k.b, sizeof k.b); }
};

/// True when triangle (a, b, c) has exactly zero area in double precision: a repeated
/// index, a repeated position, or an exactly zero edge cross product (collinear).
bool isDegenerate(const Scene& scene, uint32_t ia, uint32_t ib, uint32_t ic) {
  if (ia == ib || ib == ic || ia == ic) return true;
  const Vec3& a = scene.positions[ia];
  const Vec3& b = scene.positions[ib];
  const Vec3& c = scene.positions[ic];
  if (a == b || b == c || a == c) return true;
  return cross(b - a, c - a) == Vec3{0, 0, 0};
}

/// Removes zero-area triangles in place (keeping order); returns how many were removed.
/// InputError unless the meshes, when there are any, cover the triangles in order; the
/// triangles appended after the last one (boxes added to a loaded scene) become an
/// unnamed mesh, which no name leaves out.
void completeMeshes(Scene& scene) {
  if (scene.meshes.empty()) return;
  uint64_t next = 0;
  for (SceneMesh& m : scene.meshes) {
    for (std::string* name : {&m.node, &m.mesh, &m.material})
      if (name->size() > kMaxMeshNameBytes) *name = validUtf8Prefix(*name, kMaxMeshNameBytes);
    if (m.firstTriangle != next)
      throw InputError(scene.name + ": mesh '" + m.mesh + "' starts at triangle " + std::to_string(m.firstTriangle) +
                       ", not " + std::to_string(next));
    next += m.triangles;
  }
  if (next > scene.triangleCount())
    throw InputError(scene.name + ": its meshes hold " + std::to_string(next) + " triangles, more than its " +
                     std::to_string(scene.triangleCount()));
  if (next < scene.triangleCount())
    scene.meshes.push_back({"", "", "", uint32_t(next), uint32_t(scene.triangleCount() - next)});
}

/// Keeps the triangles `keep` says yes to, in order; the meshes' ranges follow. The closed
/// flags are the caller's to classify again.
template <class Keep>
void keepTriangles(Scene& scene, Keep keep) {
  const size_t n = scene.triangleCount();
  std::vector<SceneMesh>& meshes = scene.meshes;
  // Meshes cover every triangle in order (completeMeshes): `mesh` holds t, and its
  // triangles before any was dropped end at `meshEnd`.
  size_t kept = 0, mesh = 0, meshEnd = meshes.empty() ? n : meshes[0].triangles;
  if (!meshes.empty()) meshes[0].firstTriangle = 0;
  for (size_t t = 0; t < n; ++t) {
    while (mesh + 1 < meshes.size() && t >= meshEnd) {
      meshes[++mesh].firstTriangle = uint32_t(kept);
      meshEnd += meshes[mesh].triangles;
    }
    if (!keep(t)) {
      if (!meshes.empty()) --meshes[mesh].triangles;
      continue;
    }
    for (int c = 0; c < 3; ++c) scene.indices[3 * kept + c] = scene.indices[3 * t + c];
    ++kept;
  }
  // Empty meshes after the last triangle start where the kept ones end.
  while (mesh + 1 < meshes.size()) meshes[++mesh].firstTriangle = uint32_t(kept);
  scene.indices.resize(3 * kept);
}

size_t dropDegenerate(Scene& scene) {
  const size_t n = scene.triangleCount();
  keepTriangles(scene, [&](size_t t) {
    return !isDegenerate(scene, scene.indices[3 * t], scene.indices[3 * t + 1], scene.indices[3 * t + 2]);
  });
  return n - scene.triangleCount();
}

/// Removes vertices no triangle references, keeping the order of the others, so that the
/// hash and the bounds depend only on the geometry in use.
void compactVertices(Scene& scene) {
  constexpr uint32_t kUnused = ~uint32_t{0};
  std::vector<uint32_t> remap(scene.positions.size(), kUnused);
  for (uint32_t i : scene.indices) remap[i] = 0;
  uint32_t next = 0;
  for (size_t v = 0; v < remap.size(); ++v) {
    if (remap[v] == kUnused) continue;
    remap[v] = next;
    scene.positions[next] = scene.positions[v];
    ++next;
  }
  scene.positions.resize(next);
  for (uint32_t& i : scene.indices) i = remap[i];
}

/// Union-find over triangles with path halving and union by size.
class DisjointSets {
 public:
  explicit DisjointSets(size_t n) : parent_(n), size_(n, 1) {
    std::iota(parent_.begin(), parent_.end(), uint32_t{0});
  }
  uint32_t find(uint32_t x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }
  void unite(uint32_t a, uint32_t b) {
    a = find(a);
    b = find(b);
    if (a == b) return;
    if (size_[a] < size_[b]) std::swap(a, b);
    parent_[b] = a;
    size_[a] += size_[b];
  }

 private:
  std::vector<uint32_t> parent_;
  std::vector<uint32_t> size_;
};

/// One triangle side: the undirected edge (lo, hi) on welded ids, the triangle, and
/// whether the triangle walks it from lo to hi.
struct EdgeUse {
  uint64_t key;  // lo << 32 | hi
  uint32_t tri;
  uint32_t forward;
};

/// Fills scene.closed and the part counts of `stats`. Sorting the 3n edge uses is
/// O(n log n); a hash map of edges was not needed at a few hundred thousand triangles.
void classifyClosed(Scene& scene, SceneStats& stats) {
  const size_t n = scene.triangleCount();
  scene.closed.assign(n, 0);
  stats.parts = stats.closedParts = stats.closedTriangles = 0;
  if (n == 0) return;

  // Weld by exact position.
  std::vector<uint32_t> welded(scene.positions.size());
  {
    std::unordered_map<PositionKey, uint32_t, PositionKeyHash> ids;
    ids.reserve(scene.positions.size());
    for (size_t v = 0; v < scene.positions.size(); ++v) {
      auto [it, inserted] = ids.try_emplace(keyOf(scene.positions[v]), static_cast<uint32_t>(ids.size()));
      welded[v] = it->second;
    }
  }

  std::vector<EdgeUse> uses;
  uses.reserve(3 * n);
  for (size_t t = 0; t < n; ++t) {
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = welded[scene.indices[3 * t + k]];
      const uint32_t b = welded[scene.indices[3 * t + (k + 1) % 3]];
      const uint32_t lo = std::min(a, b), hi = std::max(a, b);
      uses.push_back({(uint64_t{lo} << 32) | hi, static_cast<uint32_t>(t), a < b ? 1u : 0u});
    }
  }
  std::sort(uses.begin(), uses.end(), [](const EdgeUse& x, const EdgeUse& y) {
    return x.key != y.key ? x.key < y.key : x.tri < y.tri;
  });

  // Triangles sharing an undirected edge join one part, whatever the edge's use count;
  // a bad edge (boundary, non-manifold or inconsistently oriented) taints its triangle.
  DisjointSets sets(n);
  std::vector<uint8_t> touchesBadEdge(n, 0);
  for (size_t i = 0; i < uses.size();) {
    size_t j = i + 1;
    while (j < uses.size() && uses[j].key == uses[i].key) ++j;
    const bool good = (j - i == 2) && uses[i].forward != uses[i + 1].forward;
    for (size_t k = i; k < j; ++k) {
      if (k > i) sets.unite(uses[i].tri, uses[k].tri);
      if (!good) touchesBadEdge[uses[k].tri] = 1;
    }
    i = j;
  }

  // Parts numbered in order of their first triangle, so the numbering is deterministic.
  constexpr uint32_t kNone = ~uint32_t{0};
  std::vector<uint32_t> partOfRoot(n, kNone);
  std::vector<uint32_t> part(n);
  std::vector<Vec3> origin;      // first vertex of the part's first triangle
  std::vector<double> volume6;   // 6 x signed volume, relative to origin
  std::vector<uint8_t> bad;
  for (size_t t = 0; t < n; ++t) {
    const uint32_t root = sets.find(static_cast<uint32_t>(t));
    if (partOfRoot[root] == kNone) {
      partOfRoot[root] = static_cast<uint32_t>(origin.size());
      origin.push_back(scene.vertex(t, 0));
      volume6.push_back(0.0);
      bad.push_back(0);
    }
    const uint32_t p = partOfRoot[root];
    part[t] = p;
    bad[p] |= touchesBadEdge[t];
    // Relative to the part's own origin: a part far from the world origin would otherwise
    // lose its volume to cancellation between large terms.
    const Vec3 a = scene.vertex(t, 0) - origin[p];
    const Vec3 b = scene.vertex(t, 1) - origin[p];
    const Vec3 c = scene.vertex(t, 2) - origin[p];
    volume6[p] += dot(a, cross(b, c));
  }

  stats.parts = origin.size();
  std::vector<uint8_t> partClosed(stats.parts);
  for (size_t p = 0; p < stats.parts; ++p) {
    partClosed[p] = !bad[p] && volume6[p] > 0.0;
    stats.closedParts += partClosed[p];
  }
  for (size_t t = 0; t < n; ++t) {
    scene.closed[t] = partClosed[part[t]];
    stats.closedTriangles += scene.closed[t];
  }
}

}  // namespace

const char* lightTypeName(SceneLight::Type type) {
  static constexpr const char* kNames[] = {"directional", "point", "spot", "area", "ambient", "unknown"};
  return kNames[size_t(type)];
}

SceneStats finalizeScene(Scene& scene) {
  if (scene.indices.size() % 3 != 0)
    throw InputError(scene.name + ": index count " + std::to_string(scene.indices.size()) +
                     " is not a multiple of 3");
  for (size_t i = 0; i < scene.indices.size(); ++i) {
    if (scene.indices[i] >= scene.positions.size())
      throw InputError(scene.name + ": index " + std::to_string(i) + " is " +
                       std::to_string(scene.indices[i]) + ", past the " +
                       std::to_string(scene.positions.size()) + " vertices");
  }
  completeMeshes(scene);
  SceneStats stats;
  stats.degenerateDropped = dropDegenerate(scene);
  compactVertices(scene);
  stats.triangles = scene.triangleCount();
  classifyClosed(scene, stats);
  return stats;
}

Hash128 sceneHash(const Scene& scene) {
  static_assert(std::endian::native == std::endian::little,
                "the scene hash is defined over little-endian bytes");
  static_assert(sizeof(Vec3) == 3 * sizeof(double), "Vec3 must be three packed doubles");
  XXH3_state_t* state = XXH3_createState();
  if (state == nullptr) throw std::bad_alloc();
  XXH3_128bits_reset(state);
  // The counts come first so that moving bytes between the arrays changes the hash.
  const uint64_t counts[2] = {scene.positions.size(), scene.indices.size()};
  XXH3_128bits_update(state, counts, sizeof counts);
  XXH3_128bits_update(state, scene.positions.data(), scene.positions.size() * sizeof(Vec3));
  XXH3_128bits_update(state, scene.indices.data(), scene.indices.size() * sizeof(uint32_t));
  XXH3_128bits_update(state, scene.closed.data(), scene.closed.size());
  // Names only where there are meshes: a generated scene hashes as its geometry alone.
  for (const SceneMesh& m : scene.meshes) {
    const uint32_t range[2] = {m.firstTriangle, m.triangles};
    XXH3_128bits_update(state, range, sizeof range);
    for (const std::string* name : {&m.node, &m.mesh, &m.material}) {
      const uint64_t size = name->size();
      XXH3_128bits_update(state, &size, sizeof size);
      XXH3_128bits_update(state, name->data(), name->size());
    }
    if (isTranslucent(m)) XXH3_128bits_update(state, m.transmittance.data(), sizeof m.transmittance);
  }
  const XXH128_hash_t h = XXH3_128bits_digest(state);
  XXH3_freeState(state);
  return {h.low64, h.high64};
}

bool meshIsNamed(const SceneMesh& m, const std::string& name) {
  return !name.empty() && (m.node == name || m.mesh == name || m.material == name);
}

Scene withoutMeshes(const Scene& scene, const std::vector<std::string>& names, const std::string& source) {
  std::vector<uint8_t> drop(scene.triangleCount(), 0);
  for (const std::string& name : names) {
    bool found = false;
    for (const SceneMesh& m : scene.meshes) {
      if (!meshIsNamed(m, name)) continue;
      found = true;
      std::fill_n(drop.begin() + m.firstTriangle, m.triangles, uint8_t{1});
    }
    if (!found) {
      // Some names it has, so that a typo is seen at once.
      std::vector<std::string> some;
      for (const SceneMesh& m : scene.meshes)
        for (const std::string* n : {&m.node, &m.mesh, &m.material})
          if (!n->empty() && some.size() < 8 && std::find(some.begin(), some.end(), *n) == some.end()) some.push_back(*n);
      std::string listed;
      for (const std::string& n : some) listed += (listed.empty() ? "'" : ", '") + n + "'";
      throw InputError(source + ": no mesh of the scene is named '" + name + "' (by its node, mesh or material)" +
                       (scene.meshes.empty() ? ": this scene's triangles have no names"
                                             : some.empty() ? "" : "; it has " + listed + (some.size() == 8 ? ", ..." : "")));
    }
  }
  Scene out = scene;
  keepTriangles(out, [&](size_t t) { return drop[t] == 0; });
  if (out.indices.empty()) throw InputError(source + ": leaving out its fixture leaves no triangle to cast a shadow");
  compactVertices(out);
  SceneStats stats;
  classifyClosed(out, stats);
  return out;
}

bool hasTranslucentMeshes(const Scene& scene) {
  return std::any_of(scene.meshes.begin(), scene.meshes.end(), [](const SceneMesh& m) { return m.triangles > 0 && isTranslucent(m); });
}

Scene opaquePart(const Scene& scene, SceneStats* stats) {
  Scene out = scene;
  if (!hasTranslucentMeshes(scene)) {
    if (stats) classifyClosed(out, *stats);
    return out;
  }
  std::vector<uint8_t> keep(scene.triangleCount(), 1);
  for (const SceneMesh& m : scene.meshes)
    if (isTranslucent(m)) std::fill_n(keep.begin() + m.firstTriangle, m.triangles, uint8_t{0});
  keepTriangles(out, [&](size_t t) { return keep[t] != 0; });
  std::erase_if(out.meshes, [](const SceneMesh& m) { return isTranslucent(m); });  // none of their triangles is left
  compactVertices(out);
  SceneStats counted;
  classifyClosed(out, counted);
  if (stats) *stats = counted;
  return out;
}

TranslucentCasters translucentCasters(const Scene& scene) {
  TranslucentCasters out;
  constexpr uint32_t kUnused = ~uint32_t{0};
  std::vector<uint32_t> remap;
  for (const SceneMesh& m : scene.meshes) {
    if (!isTranslucent(m) || m.triangles == 0) continue;
    ++out.meshes;
    if (remap.empty()) remap.assign(scene.positions.size(), kUnused);
    for (size_t t = m.firstTriangle; t < size_t(m.firstTriangle) + m.triangles; ++t) {
      for (int c = 0; c < 3; ++c) {
        const uint32_t v = scene.indices[3 * t + c];
        if (remap[v] == kUnused) {
          remap[v] = uint32_t(out.positions.size());
          out.positions.push_back(scene.positions[v]);
        }
        out.indices.push_back(remap[v]);
      }
      out.transmittance.push_back(m.transmittance);
    }
  }
  return out;
}

void sceneBounds(const Scene& scene, Vec3& lo, Vec3& hi) {
  if (scene.indices.empty()) {
    lo = hi = Vec3{};
    return;
  }
  lo = hi = scene.positions[scene.indices[0]];
  for (uint32_t i : scene.indices) {
    lo = min(lo, scene.positions[i]);
    hi = max(hi, scene.positions[i]);
  }
}

}  // namespace cpvs
