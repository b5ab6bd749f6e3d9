// Dynamic casters: the meshes of a frame placed in the world and their TOP tree for the
// artifact's sun; the bytes cpvs_shadow.glsl's CpvsCasters reads; an artifact's translucent
// casters, their bytes and their transmittance on the CPU. Compiled with
// -ffp-contract=off: the offset point is the one the shader computes with `precise`.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "cpvs/base/error.h"
#include "cpvs/runtime/runtime.h"
#include "query_kernel.h"

namespace cpvs::runtime {

namespace {

/// cpvs_shadow.glsl's CpvsCasters before its nodes (std430): the origin of the tree's
/// planes and the receivers' normal offset in doubles, the light (its direction, or a
/// point light's position relative to the origin; w 1 for the sun), the query's margins,
/// the root.
struct CasterHeader {
  double origin[3];
  double normalOffset;
  float light[3];
  float directional;
  float margin, relativeMargin;
  uint32_t firstNode, root;
};
static_assert(sizeof(CasterHeader) == 64, "cpvs_shadow.glsl's CpvsCasters header is 64 bytes");


/// The meshes placed in the world as one triangle list, each checked.
struct PlacedMeshes {
  std::vector<Vec3> positions;
  std::vector<uint32_t> indices;
  std::vector<uint8_t> closed;  // empty when no mesh said
  Vec3 lo, hi;                  // the finite positions' bounds (lo > hi: none)
};

PlacedMeshes placeMeshes(const std::vector<CasterMesh>& meshes) {
  PlacedMeshes out;
  bool anyClosed = false;
  for (size_t k = 0; k < meshes.size(); ++k) {
    const CasterMesh& m = meshes[k];
    const std::string which = "caster mesh " + std::to_string(k);
    if (m.indices.size() % 3 != 0)
      throw RuntimeError(Status::InvalidArgument, which + ": " + std::to_string(m.indices.size()) + " indices, not 3 a triangle");
    const size_t triangles = m.indices.size() / 3;
    if (!m.closed.empty() && m.closed.size() != triangles)
      throw RuntimeError(Status::InvalidArgument, which + ": " + std::to_string(m.closed.size()) + " closed flags for " +
                                                      std::to_string(triangles) + " triangles");
    for (double v : m.transform)
      if (!std::isfinite(v)) throw RuntimeError(Status::InvalidArgument, which + ": the transform is not finite");
    for (uint32_t i : m.indices)
      if (i >= m.positions.size())
        throw RuntimeError(Status::InvalidArgument, which + ": index " + std::to_string(i) + " past its " +
                                                        std::to_string(m.positions.size()) + " positions");
    if (out.positions.size() + m.positions.size() > std::numeric_limits<uint32_t>::max())
      throw RuntimeError(Status::InvalidArgument, "the caster meshes have more than 2^32 positions");
    const uint32_t base = uint32_t(out.positions.size());
    for (const Vec3& p : m.positions) out.positions.push_back(m.place(p));
    for (uint32_t i : m.indices) out.indices.push_back(base + i);
    for (size_t t = 0; t < triangles; ++t) out.closed.push_back(m.closed.empty() ? 0 : m.closed[t]);
    anyClosed |= !m.closed.empty();
  }
  if (!anyClosed) out.closed.clear();
  const double inf = std::numeric_limits<double>::infinity();
  out.lo = {inf, inf, inf};
  out.hi = -out.lo;
  for (const Vec3& p : out.positions)
    if (isFinite(p)) out.lo = min(out.lo, p), out.hi = max(out.hi, p);
  return out;
}

void checkOffset(double normalOffset) {
  if (!std::isfinite(normalOffset)) throw RuntimeError(Status::InvalidArgument, "the casters' normal offset is not finite");
}

/// The tree of the placed meshes for a light, queries from `domain` and the casters.
TopTree treeOf(const PlacedMeshes& m, const PsvLight& light, Vec3 lo, Vec3 hi, bool link) {
  TopTreeOptions options;
  options.domainLo = min(lo, m.lo);
  options.domainHi = max(hi, m.hi);
  try {
    return link ? TopTree::build(m.positions, m.indices, m.closed, light, options)
                : TopTree::frusta(m.positions, m.indices, m.closed, light, options);
  } catch (const InputError& e) {
    throw RuntimeError(Status::InvalidArgument, e.what());
  }
}

/// A tree's header for CpvsCasters / CpvsLightCasters: where its nodes start in the
/// buffer they share (0 for the sun's, alone in its buffer).
CasterHeader headerOf(const TopTree& tree, double normalOffset, uint32_t firstNode) {
  CasterHeader h{};
  const Vec3& o = tree.origin();
  h.origin[0] = o.x, h.origin[1] = o.y, h.origin[2] = o.z;
  h.normalOffset = normalOffset;
  const PsvLight& light = tree.light();
  const Vec3 l = light.directional ? light.vector : light.vector - o;
  h.light[0] = float(l.x), h.light[1] = float(l.y), h.light[2] = float(l.z);
  h.directional = light.directional ? 1.0f : 0.0f;
  h.margin = float(tree.queryMargin());
  h.relativeMargin = float(kTopQueryMargin);
  h.firstNode = firstNode;
  h.root = tree.root();
  return h;
}

template <class T>
void append(std::vector<uint8_t>& out, const T* data, size_t count) {
  const size_t at = out.size();
  out.resize(at + count * sizeof(T));
  if (count) std::memcpy(out.data() + at, data, count * sizeof(T));
}

}  // namespace

DynamicCasters::DynamicCasters(const ShadowArtifact& artifact, const std::vector<CasterMesh>& meshes, double normalOffset,
                               Build build) {
  const OrthoGrid& grid = artifact.grid();
  checkOffset(normalOffset);
  normalOffset_ = normalOffset < 0 ? grid.texelSize() : normalOffset;
  const PlacedMeshes placed = placeMeshes(meshes);
  triangles_ = placed.indices.size() / 3;
  // Queries come from the baked world and from the casters: the domain holds both.
  // (On a grid with fewer depth slices, the scene's: no point lies behind them.)
  const uint64_t R = grid.resolution(), depth = grid.depthSlices != 0 ? grid.depthSlices : R;
  Vec3 lo = grid.worldFromVoxel(Vec3{}), hi = lo;
  for (int c = 1; c < 8; ++c) {
    const Vec3 corner = grid.worldFromVoxel(Vec3{c & 1 ? double(R) : 0, c & 2 ? double(R) : 0, c & 4 ? double(depth) : 0});
    lo = min(lo, corner);
    hi = max(hi, corner);
  }
  tree_ = treeOf(placed, PsvLight::sun(grid.frame.dir), lo, hi, build == Build::Cpu);
}

const TopTree& DynamicCasters::linked() const {
  if (tree_.linked()) return tree_;
  std::call_once(linkOnce_, [this] {
    auto copy = std::make_unique<TopTree>(tree_);
    copy->link();
    cpuTree_ = std::move(copy);
  });
  return *cpuTree_;
}

bool DynamicCasters::shadowed(const Vec3& p, const Vec3& n) const {
  const Vec3 q{p.x + n.x * normalOffset_, p.y + n.y * normalOffset_, p.z + n.z * normalOffset_};
  return linked().shadowed(q);
}

std::vector<uint8_t> DynamicCasters::cornerBytes() const {
  const std::vector<double>& corners = tree_.corners();
  std::vector<double> table{tree_.buildTolerance(), 0.0};
  table.insert(table.end(), corners.begin(), corners.end());
  std::vector<uint8_t> bytes(table.size() * sizeof(double));
  std::memcpy(bytes.data(), table.data(), bytes.size());
  return bytes;
}

std::vector<uint8_t> DynamicCasters::bytesOf(const TopTree& tree) const {
  const CasterHeader h = headerOf(tree, normalOffset_, 0);
  std::vector<uint8_t> bytes;
  append(bytes, &h, 1);
  append(bytes, tree.nodes().data(), tree.nodes().size());
  return bytes;
}


std::vector<uint8_t> ShadowArtifact::translucentGpuBytes() const {
  static const TopTree none;
  const TopTree& tree = translucent_ ? *translucent_ : none;
  const CasterHeader h = headerOf(tree, grid().texelSize(), 0);
  std::vector<uint8_t> bytes;
  append(bytes, &h, 1);
  append(bytes, tree.nodes().data(), tree.nodes().size());
  return bytes;
}

std::vector<uint8_t> ShadowArtifact::transmittanceGpuBytes() const {
  std::vector<uint8_t> bytes;
  if (translucent_) append(bytes, translucent_->transmittance().data(), translucent_->transmittance().size());
  if (bytes.empty()) bytes.resize(12, 0);  // a binding is never empty
  return bytes;
}

void cpuTransmittance(const ShadowArtifact& artifact, const std::vector<Vec3>& points, const std::vector<Vec3>& normals,
                      std::vector<std::array<float, 3>>& out) {
  checkQueryShape(points.size(), normals.size(), 1);
  out.assign(points.size(), {1, 1, 1});
  const TopTree* tree = artifact.translucent();
  if (!tree || tree->root() == 0) return;
  const double d = artifact.grid().texelSize();
  tbb::parallel_for(size_t(0), points.size(), [&](size_t i) {
    const Vec3& p = points[i];
    const Vec3 n = normals.empty() ? Vec3{} : normals[i];
    out[i] = tree->transmittanceAt(Vec3{p.x + n.x * d, p.y + n.y * d, p.z + n.z * d});
  });
}

LightCasters::LightCasters(const LightArtifact& artifact, const std::vector<CasterMesh>& meshes, double normalOffset) {
  checkOffset(normalOffset);
  const PlacedMeshes placed = placeMeshes(meshes);
  triangles_ = placed.indices.size() / 3;
  const LightBundle& bundle = artifact.bundle();
  trees_.resize(bundle.lights.size());
  offsets_.resize(bundle.lights.size());
  // Each light whose reach the casters enter gets its tree; the rest none. A VPL is a
  // light too: an area light's soft lookups do not read these (see the header).
  tbb::parallel_for(size_t(0), bundle.lights.size(), [&](size_t i) {
    const BundleLight& b = bundle.lights[i];
    const PerspectiveGrid& grid = bundle.grids.at(b.firstGrid).grid;
    const double range = grid.far();
    offsets_[i] = normalOffset >= 0 ? normalOffset : 2 * range * grid.tanHalfFov() / double(grid.resolution());
    const Vec3 at = b.light.position, reach{range, range, range};
    const Vec3 nearest = max(placed.lo, min(at, placed.hi));
    if (b.light.area != 0 || !(placed.lo.x <= placed.hi.x) || length(nearest - at) > range) return;
    trees_[i] = std::make_unique<TopTree>(treeOf(placed, PsvLight::point(at), at - reach, at + reach, true));
  });
}

bool LightCasters::shadowed(size_t light, const Vec3& p, const Vec3& n) const {
  const TopTree* t = tree(light);
  if (!t) return false;
  const double d = offsets_[light];
  return t->shadowed(Vec3{p.x + n.x * d, p.y + n.y * d, p.z + n.z * d});
}

std::vector<uint8_t> LightCasters::headerBytes() const {
  std::vector<uint8_t> bytes;
  uint32_t first = 0;
  for (size_t i = 0; i < trees_.size(); ++i) {
    CasterHeader h{};
    if (trees_[i]) {
      h = headerOf(*trees_[i], offsets_[i], first);
      first += uint32_t(trees_[i]->nodes().size());
    }
    append(bytes, &h, 1);
  }
  return bytes;
}

std::vector<uint8_t> LightCasters::nodeBytes() const {
  std::vector<uint8_t> bytes;
  for (const auto& t : trees_)
    if (t) append(bytes, t->nodes().data(), t->nodes().size());
  if (bytes.empty()) {
    const TopNode none{{0, 0, 0, 0}, 0, 0, 0, 0};
    append(bytes, &none, 1);  // a buffer is never empty
  }
  return bytes;
}

}  // namespace cpvs::runtime
