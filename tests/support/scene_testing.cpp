#include "scene_testing.h"

#include "cpvs/bake/bake_plan.h"

namespace cpvs::testing {

std::string sharedScenesDir() {
  std::filesystem::path p = std::filesystem::path(CPVS_SOURCE_DIR) / ".." / "shared" / "scenes";
  return std::filesystem::is_directory(p) ? p.string() : std::string();
}

namespace {

// One texel's ray (from `from` along `dir`, its parameter the depth `texels` slices)
// against every triangle in double precision, classified by the renderer's rule.
// `sliceFraction(t)` is where depth t lies within its slice, for the ambiguity test.
template <class Texels, class SliceFraction>
void bruteForceRay(const Scene& scene, const Vec3& from, const Vec3& dir, ClosedMode closed, ExitMode exit,
                   const Texels& texels, double tieDistance, SliceFraction sliceFraction, uint32_t& lo, uint32_t& hi,
                   bool& ambiguous) {
  std::vector<RayHit> hits;
  ambiguous = false;
  for (size_t t = 0; t < scene.triangleCount(); ++t) {
    Vec3 a = scene.vertex(t, 0), b = scene.vertex(t, 1), c = scene.vertex(t, 2);
    Vec3 e1 = b - a, e2 = c - a, p = cross(dir, e2);
    double det = dot(e1, p);
    if (std::abs(det) < 1e-300) continue;  // parallel to the ray
    Vec3 s = from - a;
    double u = dot(s, p) / det;
    Vec3 q = cross(s, e1);
    double v = dot(dir, q) / det, w = 1 - u - v;
    double dist = dot(e2, q) / det;
    const double hair = 1e-5;
    bool inside = u >= 0 && v >= 0 && w >= 0;
    if (std::min({u, v, w}) > -hair && std::min({u, v, w}) < hair && dist > 0) ambiguous = true;
    if (!inside || dist < 0) continue;
    const double frac = sliceFraction(dist);
    if (frac < 1e-4 || frac > 1 - 1e-4) ambiguous = true;
    bool isClosed = closed == ClosedMode::On || (closed == ClosedMode::Auto && scene.closed[t] != 0);
    hits.push_back(RayHit{dist, uint32_t(t), dot(cross(e1, e2), dir) < 0, isClosed});
  }
  hits.resize(size_t(orderCrossings(hits.data(), int(hits.size()), tieDistance)));
  if (exit == ExitMode::Approx) {
    // The approximate pass only ever sees the first hit and the first closed back face.
    std::vector<RayHit> kept;
    if (!hits.empty()) kept.push_back(hits[0]);
    for (size_t i = 1; i < hits.size(); ++i)
      if (hits[i].closed && !hits[i].front) {
        kept.push_back(hits[i]);
        break;
      }
    hits = kept;
  }
  classifyTexel(hits.data(), int(hits.size()), exit == ExitMode::Exact, texels, lo, hi);
}

}  // namespace

void bruteForceTexel(const Scene& scene, const OrthoGrid& grid, ClosedMode closed, ExitMode exit, uint64_t x,
                            uint64_t y, uint32_t& lo, uint32_t& hi, bool& ambiguous) {
  const Vec3 from = grid.worldFromVoxel(Vec3{double(x) + 0.5, double(y) + 0.5, 0.0});
  const double slicesPerUnit = double(grid.resolution()) / grid.depthExtent;
  bruteForceRay(scene, from, grid.frame.dir, closed, exit, grid.texelMapping(grid.origin), grid.depthExtent * 1e-6,
                [&](double t) { return t * slicesPerUnit - std::floor(t * slicesPerUnit); }, lo, hi, ambiguous);
}

void bruteForceSpotTexel(const Scene& scene, const PerspectiveGrid& grid, double tanCone, ClosedMode closed,
                         ExitMode exit, uint64_t x, uint64_t y, uint32_t& lo, uint32_t& hi, bool& ambiguous) {
  if (grid.coneMissesTexel(x, y, tanCone)) {
    lo = 0, hi = uint32_t(grid.resolution()), ambiguous = false;
    return;
  }
  // The texel's ray written out (NOTES §1.2.3): from the light, at unit speed along the axis.
  const double R = double(grid.resolution()), t = grid.tanHalfFov();
  const double a = ((double(x) + 0.5) * 2 / R - 1) * t, b = ((double(y) + 0.5) * 2 / R - 1) * t;
  const Vec3 dir = grid.frame().dir + grid.frame().u * a + grid.frame().v * b;
  const Vec3 from = grid.position();
  bruteForceRay(scene, from, dir, closed, exit, grid.texelMapping(Vec3{}), grid.far() * 1e-6,
                [&](double zv) {
                  const double z = grid.voxelFromWorld(from + dir * zv).z;
                  return z - std::floor(z);
                },
                lo, hi, ambiguous);
}

bool openLamp(const LampCase& c, Scene& scene, Vec3& centre, std::optional<PerspectiveGrid>& grid) {
  std::string spec = c.scene;
  if (c.shared) {
    const std::string dir = sharedScenesDir();
    if (dir.empty()) return false;
    spec = dir + "/" + c.scene;
  }
  scene = openScene(spec);
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  const double size = length(hi - lo);
  centre = (lo + hi) * 0.5;
  const Vec3 lamp = centre + Vec3{c.offset.x * (hi.x - lo.x), c.offset.y * (hi.y - lo.y), c.offset.z * (hi.z - lo.z)};
  grid.emplace(lamp, LightFrame::fromDirection(c.dir), c.tanHalfFov, c.near * size, c.far * size, c.log2R);
  return true;
}

void bruteForceDepths(const Scene& scene, const OrthoGrid& grid, ClosedMode closed, ExitMode exit,
                             TexelSlices& out, std::vector<uint8_t>& ambiguous) {
  const uint64_t R = grid.resolution();
  out.firstUndefined.assign(R * R, 0);
  out.firstShadowed.assign(R * R, 0);
  ambiguous.assign(R * R, 0);
  for (uint64_t y = 0; y < R; ++y)
    for (uint64_t x = 0; x < R; ++x) {
      bool amb = false;
      bruteForceTexel(scene, grid, closed, exit, x, y, out.firstUndefined[y * R + x], out.firstShadowed[y * R + x], amb);
      ambiguous[y * R + x] = amb;
    }
}

Dag bakeWith(const Scene& scene, const OrthoGrid& grid, const BakeOptions& options) {
  const BakeScene prepared(scene, grid, options.renderer);
  return bakeGrid(prepared, options);
}

CpvsArtifact localArtifact(const Scene& scene, const OrthoGrid& grid, BakeOptions options,
                           const ReceiverDeclaration& receivers) {
  options.receivers = receivers.kind;
  if (receivers.kind != ReceiverKind::Everywhere) options.receiverPcf = uint8_t(receivers.maxPcf);
  const BakeScene prepared(scene, grid, options.renderer, 0, receivers);
  Scene copy = scene;
  const SceneStats stats = finalizeScene(copy);
  CpvsArtifact a;
  a.grid = grid;
  a.options = options;
  a.sceneHash = sceneHash(scene);
  a.receiverHash = receiverHash(receivers);
  a.plan = planJson(planBake(scene, stats, options, receivers, prepared.raster(), prepared.receivers()));
  a.dag = bakeGrid(prepared, options);
  return a;
}

Dag bakeTileWith(const Scene& scene, const OrthoGrid& grid, uint64_t tileX, uint64_t tileY, const BakeOptions& options) {
  const BakeScene prepared(scene, grid, options.renderer);
  return bakeTile(prepared, tileX, tileY, options);
}

void appendQuad(Scene& s, Vec3 a, Vec3 b, Vec3 c, Vec3 d) {
  const uint32_t base = uint32_t(s.positions.size());
  for (const Vec3& p : {a, b, c, d}) s.positions.push_back(p);
  for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) s.indices.push_back(base + i);
}

}  // namespace cpvs::testing
