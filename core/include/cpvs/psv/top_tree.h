// Partitioned shadow volumes (seed 003): exact hard shadows of a triangle soup from one
// light, answered per point by a TOP tree, a ternary partition of the triangles' shadow
// frusta built by randomized insertion. What moves casts its shadows through it (built per
// frame), and it is an exact oracle that shares no code with the ray tracer.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "cpvs/base/vec3.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

/// The light whose shadows a tree holds: the sun (a direction, where its light travels)
/// or a point light (a position). A spot light is a point light whose cone the caller
/// applies.
struct PsvLight {
  bool directional = true;
  Vec3 vector;  // directional: the unit direction light travels; point: the light's position

  static PsvLight sun(const Vec3& direction) { return {true, direction}; }
  static PsvLight point(const Vec3& position) { return {false, position}; }
};

/// How a tree is built; each optimisation of the seed can be turned off (for the
/// benchmark). The defaults are the seed's.
struct TopTreeOptions {
  uint64_t seed = 1;              // of the insertion order
  bool randomOrder = true;        // false: triangles in their given order (seed Fig. 4a's quadratic case)
  bool wedges = true;             // the inter child's wedge test (seed §3.5)
  bool frontFaceCulling = true;   // triangles of closed parts facing the light cast nothing (seed §4.2)
  /// Where queries will be (a box, min and max); empty (lo > hi): the casters' bounds
  /// (with a point light's position). Answers are exact (equal inAnyFrustum) inside it.
  Vec3 domainLo{1, 1, 1}, domainHi{0, 0, 0};
};

/// One node of the tree: 32 bytes, the same on the CPU and in a GPU buffer. A frustum is
/// four consecutive nodes 4k+1 .. 4k+4: its three shadow planes (through the light and
/// an edge), then its capping plane (the triangle's plane), so a node is a capping plane
/// exactly when its index is a multiple of 4. Inside a frustum is negative: a point is in
/// it when all four planes' distances are < 0. Index 0 is the empty leaf. A shadow plane's
/// neg child is the next plane of its frustum; every child's index exceeds its parent's.
struct TopNode {
  float plane[4];              // n.x, n.y, n.z, w: distance = n . (p - origin) + w
  uint32_t pos, inter, neg;    // the triangles strictly on the positive side, crossing it, on the negative
  float wedge;                 // shadow planes: the bound of the inter child's frusta (see TopTree)
};
static_assert(sizeof(TopNode) == 32);

/// A query's answer with a bounded stack (as a GPU walks it).
enum class TopAnswer : uint8_t { Lit, Shadowed, Overflow };

struct TopQueryStats {
  uint32_t visited = 0;   // nodes whose plane was evaluated
  uint32_t maxStack = 0;  // deepest the stack was
};

struct TopBuildStats {
  size_t triangles = 0;        // given
  size_t frusta = 0;           // in the tree
  size_t degenerate = 0;       // skipped: zero area, non-finite, or edge-on to the light (no shadow of any area)
  size_t culled = 0;           // skipped: closed and facing the light (front-face culling)
  uint64_t classified = 0;     // triangle-against-plane tests of the insertion (Alg. 1's work)
  uint32_t depth = 0;          // the longest path of frusta from the root
};

/// A TOP tree over one light's shadow frusta. Planes are floats relative to `origin()`
/// (the domain's centre); a point's distance is evaluated in float in one fixed order,
/// so a GPU that rounds alike answers alike. Build and query classify with margins
/// (vertices within 2^-18 of the domain's extent of a plane count as on it; a query
/// descends both sides within 2^-16): shared edges do not fatten the tree and the float
/// rounding of planes never hides a frustum. A query therefore answers exactly what
/// inAnyFrustum, the brute force over every frustum with the same predicates, answers.
///
/// The wedge of a shadow plane bounds every point of its inter child's frusta: for the
/// sun a slab |distance| <= wedge (a prism along the light stays within the slab of its
/// triangle), for a point light a sine, |distance| <= wedge * |p - light| (the largest
/// vertex distance over the triangle's distance from the light: conservative also for a
/// triangle whose edges bulge past its vertices in angle).
class TopTree {
 public:
  TopTree() = default;
  /// Triangles as positions and 3 indices each; `closed` (empty, or one flag per
  /// triangle) marks those of closed, outward-facing parts, the only ones front-face
  /// culling may drop. InputError for an index out of range, a non-finite light or a
  /// zero direction. Deterministic for a seed: the same nodes for any thread count.
  static TopTree build(const std::vector<Vec3>& positions, const std::vector<uint32_t>& indices,
                       const std::vector<uint8_t>& closed, const PsvLight& light, const TopTreeOptions& options = {});
  /// The scene's triangles (its closed flags).
  static TopTree build(const Scene& scene, const PsvLight& light, const TopTreeOptions& options = {});
  /// The frusta without the tree (for a device that inserts them itself, seed 003 §3.6):
  /// every node's plane in its frustum's place, each frustum's chain of neg links from
  /// its first plane to its capping plane, no other child and no wedge; corners() holds
  /// what an insertion classifies with. link() makes it build()'s tree.
  static TopTree frusta(const std::vector<Vec3>& positions, const std::vector<uint32_t>& indices,
                        const std::vector<uint8_t>& closed, const PsvLight& light, const TopTreeOptions& options = {});
  /// A linked tree as stored (an artifact's translucent casters): its nodes, light,
  /// origin, margins and, when not empty, each frustum's transmittance. Nothing of it is
  /// trusted: InputError unless it is a tree a walk cannot trip on (4F + 1 nodes, each
  /// frustum's chain of planes in place, every other child the first plane of a later
  /// frustum and every frustum but the first the child of exactly one node, finite
  /// planes, wedges not negative), the light and origin finite, the margins positive, and
  /// every transmittance in [0, 1].
  static TopTree fromNodes(std::vector<TopNode> nodes, const PsvLight& light, const Vec3& origin, double buildTolerance,
                           double queryMargin, std::vector<std::array<float, 3>> transmittance = {});
  /// Inserts the frusta (build()'s tree, the same nodes); nothing when linked already.
  void link();
  bool linked() const { return linked_; }
  /// Until linked: kTopCornerDoubles a frustum in rank order, its triangle's three
  /// corners relative to the origin and, for a point light, the triangle's distance from it.
  const std::vector<double>& corners() const { return corners_; }

  /// Whether p is in some triangle's shadow (unbounded stack). The tree must be linked,
  /// as must query()'s.
  bool shadowed(const Vec3& p) const;
  /// The walk with a stack of `stackLimit` entries, as a GPU would: Overflow when it
  /// does not suffice (answer it with shadowed()).
  TopAnswer query(const Vec3& p, uint32_t stackLimit, TopQueryStats* stats = nullptr) const;
  /// Translucent casters (glass, water, leaves on cards): each frustum's transmittance,
  /// from one a caller's triangle (RGB, each in [0, 1]); InvalidArgument otherwise. Build
  /// such a tree without front-face culling: light crosses both sides of a closed pane.
  void setTransmittance(const std::vector<std::array<float, 3>>& perTriangle);
  /// By frustum (rank), once set.
  const std::vector<std::array<float, 3>>& transmittance() const { return transmittance_; }
  /// The light reaching p through the translucent casters: the product of the
  /// transmittance of every frustum holding p, per channel (1: none). The walk goes on past
  /// a capping plane p is behind (seed 003 §3.4), in no particular order; the products
  /// are the same up to float rounding. stackLimit and Overflow as query()'s.
  TopAnswer transmittanceAt(const Vec3& p, uint32_t stackLimit, std::array<float, 3>& out,
                            TopQueryStats* stats = nullptr) const;
  std::array<float, 3> transmittanceAt(const Vec3& p) const;  // unbounded
  /// Brute force: p is inside one of the frusta by the same predicates.
  bool inAnyFrustum(const Vec3& p) const;
  /// Indices (into nodes' frusta) of every frustum holding p, by brute force.
  std::vector<uint32_t> frustaHolding(const Vec3& p) const;

  const std::vector<TopNode>& nodes() const { return nodes_; }
  /// The root's index (0: no frustum, every point lit).
  uint32_t root() const { return nodes_.size() > 1 ? 1u : 0u; }
  size_t frustumCount() const { return (nodes_.size() - 1) / 4; }
  /// The caller's triangle that frustum k was made from.
  uint32_t triangleOf(size_t k) const { return triangleOf_[k]; }
  const PsvLight& light() const { return light_; }
  const Vec3& origin() const { return origin_; }
  /// p relative to the origin in float, as every plane reads it.
  void relative(const Vec3& p, float out[3]) const;
  /// The build's tolerance (vertices on a plane) and the query's margin, in scene units
  /// (for a point light, plus the same fraction of the distance to the light).
  double buildTolerance() const { return buildTolerance_; }
  double queryMargin() const { return queryMargin_; }
  const TopBuildStats& buildStats() const { return stats_; }
  size_t bytes() const { return nodes_.size() * sizeof(TopNode); }

  /// The distance of p (relative, float) to node i's plane, in float, in the fixed order.
  static float distance(const TopNode& n, const float p[3]);

 private:
  /// The walk of query() and transmittanceAt(): inside(k) is called for each frustum k
  /// holding p and ends the walk (Shadowed) when it returns true.
  template <class Inside>
  TopAnswer walk(const Vec3& p, uint32_t stackLimit, TopQueryStats* stats, Inside&& inside) const;
  /// Whether frustum k holds the point x (relative): all four distances < 0.
  bool holds(size_t k, const float x[3]) const;

  std::vector<TopNode> nodes_ = std::vector<TopNode>(1, TopNode{{0, 0, 0, 0}, 0, 0, 0, 0});  // index 0: the leaf
  std::vector<uint32_t> triangleOf_;
  std::vector<double> corners_;  // until linked
  std::vector<std::array<float, 3>> transmittance_;  // by rank, when set
  bool linked_ = true, wedges_ = true;
  PsvLight light_;
  Vec3 origin_;
  float lightRel_[3] = {0, 0, 0};  // a point light relative to the origin
  double buildTolerance_ = 0, queryMargin_ = 0;
  TopBuildStats stats_;
};

/// Doubles a frustum in TopTree::corners().
constexpr size_t kTopCornerDoubles = 10;

/// Relative tolerances of the build (a vertex on a plane) and of the query's margins, as
/// fractions of the domain's extent (and, for a point light, of the distance to it).
constexpr double kTopBuildTolerance = 0x1p-18;
constexpr double kTopQueryMargin = 0x1p-16;

}  // namespace cpvs
