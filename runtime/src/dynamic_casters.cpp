// Dynamic casters: the meshes of a frame placed in the world and their TOP tree for the
// artifact's sun; the bytes cpvs_shadow.glsl's CpvsCasters reads. Compiled with
// -ffp-contract=off: the offset point is the one the shader computes with `precise`.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "cpvs/base/error.h"
#include "cpvs/runtime/runtime.h"

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
  uint32_t pad, root;
};
static_assert(sizeof(CasterHeader) == 64, "cpvs_shadow.glsl's CpvsCasters header is 64 bytes");

Vec3 placed(const std::array<double, 12>& m, const Vec3& p) {
  return {m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3], m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
          m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11]};
}

}  // namespace

DynamicCasters::DynamicCasters(const ShadowArtifact& artifact, const std::vector<CasterMesh>& meshes, double normalOffset,
                               Build build) {
  const OrthoGrid& grid = artifact.grid();
  if (!std::isfinite(normalOffset))
    throw RuntimeError(Status::InvalidArgument, "the casters' normal offset is not finite");
  normalOffset_ = normalOffset < 0 ? grid.texelSize() : normalOffset;
  std::vector<Vec3> positions;
  std::vector<uint32_t> indices;
  std::vector<uint8_t> closed;
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
    if (positions.size() + m.positions.size() > std::numeric_limits<uint32_t>::max())
      throw RuntimeError(Status::InvalidArgument, "the caster meshes have more than 2^32 positions");
    const uint32_t base = uint32_t(positions.size());
    for (const Vec3& p : m.positions) positions.push_back(placed(m.transform, p));
    for (uint32_t i : m.indices) indices.push_back(base + i);
    for (size_t t = 0; t < triangles; ++t) closed.push_back(m.closed.empty() ? 0 : m.closed[t]);
    anyClosed |= !m.closed.empty();
  }
  if (!anyClosed) closed.clear();
  triangles_ = indices.size() / 3;
  // Queries come from the baked world and from the casters: the domain holds both.
  TopTreeOptions options;
  const uint64_t R = grid.resolution();
  options.domainLo = options.domainHi = grid.worldFromVoxel(Vec3{});
  for (int c = 1; c < 8; ++c) {
    const Vec3 corner = grid.worldFromVoxel(Vec3{c & 1 ? double(R) : 0, c & 2 ? double(R) : 0, c & 4 ? double(R) : 0});
    options.domainLo = min(options.domainLo, corner);
    options.domainHi = max(options.domainHi, corner);
  }
  for (const Vec3& p : positions)
    if (isFinite(p)) {
      options.domainLo = min(options.domainLo, p);
      options.domainHi = max(options.domainHi, p);
    }
  try {
    tree_ = build == Build::Cpu ? TopTree::build(positions, indices, closed, PsvLight::sun(grid.frame.dir), options)
                                : TopTree::frusta(positions, indices, closed, PsvLight::sun(grid.frame.dir), options);
  } catch (const InputError& e) {
    throw RuntimeError(Status::InvalidArgument, e.what());
  }
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
  CasterHeader h{};
  const Vec3& o = tree.origin();
  h.origin[0] = o.x, h.origin[1] = o.y, h.origin[2] = o.z;
  h.normalOffset = normalOffset_;
  const PsvLight& light = tree.light();
  const Vec3 l = light.directional ? light.vector : light.vector - o;
  h.light[0] = float(l.x), h.light[1] = float(l.y), h.light[2] = float(l.z);
  h.directional = light.directional ? 1.0f : 0.0f;
  h.margin = float(tree.queryMargin());
  h.relativeMargin = float(kTopQueryMargin);
  h.root = tree.root();
  const std::vector<TopNode>& nodes = tree.nodes();
  std::vector<uint8_t> bytes(sizeof h + nodes.size() * sizeof(TopNode));
  std::memcpy(bytes.data(), &h, sizeof h);
  std::memcpy(bytes.data() + sizeof h, nodes.data(), nodes.size() * sizeof(TopNode));
  return bytes;
}

}  // namespace cpvs::runtime
