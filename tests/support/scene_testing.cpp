#include "scene_testing.h"

#include "cpvs/bake/bake_plan.h"
#include "cpvs/base/file.h"
#include "cpvs/psv/translucent_tree.h"
#include "cpvs/scene/boxes.h"

#include <cstdio>
#include <cstring>

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
  bruteForceRay(scene, from, grid.frame.dir, closed, exit, grid.texelMapping(grid.origin), grid.sceneDepthExtent() * 1e-6,
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
  if (hasTranslucentMeshes(scene))
    a.translucent = std::make_shared<const TopTree>(translucentTree(scene, PsvLight::sun(grid.frame.dir)));
  return a;
}

Dag bakeTileWith(const Scene& scene, const OrthoGrid& grid, uint64_t tileX, uint64_t tileY, const BakeOptions& options) {
  const BakeScene prepared(scene, grid, options.renderer);
  return bakeTile(prepared, tileX, tileY, options);
}

void writeGlb(const Scene& scene, const std::string& path) {
  std::vector<SceneMesh> meshes = scene.meshes;
  if (meshes.empty()) meshes.push_back({"all", "all", "", 0, uint32_t(scene.triangleCount()), {0, 0, 0}});
  std::vector<uint8_t> bin;
  auto append = [&bin](const void* p, size_t n) {
    bin.insert(bin.end(), static_cast<const uint8_t*>(p), static_cast<const uint8_t*>(p) + n);
  };
  float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
  for (const Vec3& p : scene.positions) {
    const float f[3] = {float(p.x), float(p.y), float(p.z)};
    append(f, sizeof f);
    for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], f[c]), hi[c] = std::max(hi[c], f[c]);
  }
  const size_t indexOffset = bin.size();
  append(scene.indices.data(), scene.indices.size() * 4);
  std::string nodes, gltfMeshes, materials, accessors, sceneNodes;
  char buf[512];
  std::snprintf(buf, sizeof buf,
                R"({"bufferView": 0, "componentType": 5126, "count": %zu, "type": "VEC3", "min": [%.9g, %.9g, %.9g], "max": [%.9g, %.9g, %.9g]})",
                scene.positions.size(), lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
  accessors = buf;
  for (size_t m = 0; m < meshes.size(); ++m) {
    const SceneMesh& mesh = meshes[m];
    const std::string sep = m ? ", " : "";
    std::snprintf(buf, sizeof buf, R"(, {"bufferView": 1, "byteOffset": %zu, "componentType": 5125, "count": %u, "type": "SCALAR"})",
                  size_t(mesh.firstTriangle) * 12, mesh.triangles * 3);
    accessors += buf;
    gltfMeshes += sep + R"({"name": ")" + mesh.mesh + R"(", "primitives": [{"attributes": {"POSITION": 0}, "indices": )" +
                  std::to_string(m + 1) + R"(, "material": )" + std::to_string(m) + "}]}";
    if (isTranslucent(mesh)) {
      std::snprintf(buf, sizeof buf,
                    R"({"name": "%s", "pbrMetallicRoughness": {"baseColorFactor": [%.9g, %.9g, %.9g, 1]}, "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1}}})",
                    mesh.material.c_str(), mesh.transmittance[0], mesh.transmittance[1], mesh.transmittance[2]);
      materials += sep + buf;
    } else {
      materials += sep + R"({"name": ")" + mesh.material + R"("})";
    }
    nodes += sep + R"({"name": ")" + mesh.node + R"(", "mesh": )" + std::to_string(m) + "}";
    sceneNodes += sep + std::to_string(m);
  }
  while (bin.size() % 4) bin.push_back(0);
  std::string json = R"({"asset": {"version": "2.0"}, "extensionsUsed": ["KHR_materials_transmission"], "scene": 0, "scenes": [{"nodes": [)" +
                     sceneNodes + R"(]}], "nodes": [)" + nodes + R"(], "meshes": [)" + gltfMeshes + R"(], "materials": [)" +
                     materials + R"(], "buffers": [{"byteLength": )" + std::to_string(bin.size()) +
                     R"(}], "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": )" + std::to_string(indexOffset) +
                     R"(}, {"buffer": 0, "byteOffset": )" + std::to_string(indexOffset) + R"(, "byteLength": )" +
                     std::to_string(scene.indices.size() * 4) + R"(}], "accessors": [)" + accessors + "]}";
  while (json.size() % 4) json.push_back(' ');
  std::vector<uint8_t> glb;
  auto word = [&glb](uint32_t v) { for (int i = 0; i < 4; ++i) glb.push_back(uint8_t(v >> (8 * i))); };
  word(0x46546C67);  // "glTF"
  word(2);
  word(uint32_t(12 + 8 + json.size() + 8 + bin.size()));
  word(uint32_t(json.size()));
  word(0x4E4F534A);  // "JSON"
  glb.insert(glb.end(), json.begin(), json.end());
  word(uint32_t(bin.size()));
  word(0x004E4942);  // "BIN\0"
  glb.insert(glb.end(), bin.begin(), bin.end());
  writeFileAtomic(path, glb);
}

Scene glassCity() {
  Scene s = openScene("city:3:5");
  Vec3 lo, hi;
  sceneBounds(s, lo, hi);
  s.meshes = {{"city", "blocks", "stone", 0, uint32_t(s.triangleCount()), {0, 0, 0}}};
  const Vec3 size = hi - lo;
  auto at = [&](double x, double y, double z) { return Vec3{lo.x + x * size.x, lo.y + y * size.y, lo.z + z * size.z}; };
  auto addMesh = [&s](const char* node, const char* material, std::array<float, 3> t, auto&& build) {
    const uint32_t first = uint32_t(s.triangleCount());
    build();
    s.meshes.push_back({node, node, material, first, uint32_t(s.triangleCount()) - first, t});
  };
  // Panes facing up (counter-clockwise from above) and one facing down.
  addMesh("pane", "green glass", {0.6f, 0.9f, 0.5f},
          [&] { appendQuad(s, at(0.1, 0.3, 0.1), at(0.1, 0.3, 0.6), at(0.6, 0.3, 0.6), at(0.6, 0.3, 0.1)); });
  addMesh("upper", "amber glass", {0.9f, 0.6f, 0.3f},
          [&] { appendQuad(s, at(0.3, 0.4, 0.3), at(0.9, 0.4, 0.3), at(0.9, 0.4, 0.9), at(0.3, 0.4, 0.9)); });
  addMesh("box", "blue glass", {0.4f, 0.6f, 0.95f}, [&] { appendBox(s, at(0.65, 0.2, 0.05), at(0.95, 0.3, 0.25)); });
  finalizeScene(s);
  return s;
}

void appendQuad(Scene& s, Vec3 a, Vec3 b, Vec3 c, Vec3 d) {
  const uint32_t base = uint32_t(s.positions.size());
  for (const Vec3& p : {a, b, c, d}) s.positions.push_back(p);
  for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) s.indices.push_back(base + i);
}

}  // namespace cpvs::testing
