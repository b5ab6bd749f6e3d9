#include "cpvs/scene/mesh_file.h"

#include <bit>
#include <cstring>

#include "cpvs/base/error.h"

namespace cpvs {
namespace {

static_assert(std::endian::native == std::endian::little, "the scene mesh file is little-endian");

constexpr char kMagic[8] = {'C', 'P', 'V', 'S', 'M', 'E', 'S', 'H'};
// 2: a light keeps its range; 3: the meshes' names (an older mesh is refused, and its
// scene imported again); 4: each light's rectangle (an area light's edges) and the
// volume media; 5: each mesh's transmittance. An older file is refused, and its scene
// imported again: read as opaque, its glass would cast as the workers' fresh import does not.
constexpr uint32_t kVersion = 5, kOldestVersion = 5;
constexpr uint32_t kMaxNameBytes = 4096;

struct Writer {
  std::vector<uint8_t> bytes;
  void raw(const void* p, size_t n) {
    const size_t at = bytes.size();
    bytes.resize(at + n);
    if (n) std::memcpy(bytes.data() + at, p, n);
  }
  template <class T>
  void put(T v) {
    raw(&v, sizeof v);
  }
  void text(const std::string& s) {
    put<uint32_t>(uint32_t(s.size()));
    raw(s.data(), s.size());
  }
  void vec(const Vec3& v) {
    put(v.x);
    put(v.y);
    put(v.z);
  }
};

struct Reader {
  const uint8_t* data;
  size_t size, pos = 0;
  const std::string& source;
  [[noreturn]] void fail(const std::string& why) const { throw FormatError(source + ": not a usable scene mesh: " + why); }
  const uint8_t* take(uint64_t n, const char* what) {
    if (n > size - pos) fail(std::string("it ends inside the ") + what);
    const uint8_t* p = data + pos;
    pos += size_t(n);
    return p;
  }
  template <class T>
  T get(const char* what) {
    T v;
    std::memcpy(&v, take(sizeof v, what), sizeof v);
    return v;
  }
  /// A count of elements of `each` bytes that must still fit in the file.
  uint64_t count(uint64_t each, const char* what) {
    const uint64_t n = get<uint64_t>(what);
    if (n > (size - pos) / each) fail(std::string("it declares more ") + what + " than it holds");
    return n;
  }
  std::string text(const char* what) {
    const uint32_t n = get<uint32_t>(what);
    if (n > kMaxNameBytes) fail(std::string("a ") + what + " of " + std::to_string(n) + " bytes");
    const uint8_t* p = take(n, what);
    return std::string(reinterpret_cast<const char*>(p), n);
  }
  Vec3 vec(const char* what) {
    Vec3 v;
    v.x = get<double>(what);
    v.y = get<double>(what);
    v.z = get<double>(what);
    return v;
  }
};

}  // namespace

std::vector<uint8_t> encodeSceneMesh(const Scene& scene, const SceneStats& stats) {
  Writer w;
  w.raw(kMagic, sizeof kMagic);
  w.put<uint32_t>(kVersion);
  w.put<uint32_t>(0);
  for (size_t s : {stats.triangles, stats.degenerateDropped, stats.closedTriangles, stats.parts, stats.closedParts})
    w.put<uint64_t>(s);
  const Hash128 geometry = sceneHash(scene);
  w.raw(&geometry, sizeof geometry);
  w.text(scene.name.substr(0, kMaxNameBytes));
  w.put<uint64_t>(scene.positions.size());
  for (const Vec3& p : scene.positions) w.vec(p);
  w.put<uint64_t>(scene.indices.size());
  w.raw(scene.indices.data(), scene.indices.size() * sizeof(uint32_t));
  w.put<uint64_t>(scene.closed.size());
  w.raw(scene.closed.data(), scene.closed.size());
  w.put<uint64_t>(scene.lights.size());
  for (const SceneLight& l : scene.lights) {
    w.text(l.name.substr(0, kMaxNameBytes));
    w.put<uint8_t>(uint8_t(l.type));
    w.vec(l.position);
    w.vec(l.direction);
    w.vec(l.color);
    w.put(l.innerConeDeg);
    w.put(l.outerConeDeg);
    w.put(l.range);
    w.vec(l.edgeU);
    w.vec(l.edgeV);
  }
  w.put<uint64_t>(scene.media.size());
  for (const SceneMedium& m : scene.media) {
    w.text(m.material.substr(0, kMaxNameBytes));
    w.put(m.absorption);
  }
  w.put<uint64_t>(scene.meshes.size());
  for (const SceneMesh& m : scene.meshes) {
    for (const std::string* name : {&m.node, &m.mesh, &m.material}) w.text(name->substr(0, kMaxNameBytes));
    w.put(m.firstTriangle);
    w.put(m.triangles);
    for (float c : m.transmittance) w.put(c);
  }
  const Hash128 check = contentHash(w.bytes.data(), w.bytes.size());
  w.raw(&check, sizeof check);
  return std::move(w.bytes);
}

Scene decodeSceneMesh(const uint8_t* data, size_t size, const std::string& source, SceneStats* stats) {
  Reader r{data, size, 0, source};
  if (size < sizeof kMagic + 8 + sizeof(Hash128) || std::memcmp(data, kMagic, sizeof kMagic) != 0)
    r.fail("no CPVSMESH magic");
  Hash128 stored;
  std::memcpy(&stored, data + size - sizeof stored, sizeof stored);
  if (contentHash(data, size - sizeof stored) != stored) r.fail("its checksum does not match (damaged or cut short)");
  r.size = size - sizeof stored;
  r.pos = sizeof kMagic;
  const uint32_t version = r.get<uint32_t>("header");
  if (version < kOldestVersion || version > kVersion)
    r.fail("format version " + std::to_string(version) + " (this build reads versions " + std::to_string(kOldestVersion) +
           " to " + std::to_string(kVersion) + ")");
  r.get<uint32_t>("header");
  SceneStats s;
  for (size_t* field : {&s.triangles, &s.degenerateDropped, &s.closedTriangles, &s.parts, &s.closedParts})
    *field = size_t(r.get<uint64_t>("statistics"));
  Hash128 geometry;
  std::memcpy(&geometry, r.take(sizeof geometry, "geometry hash"), sizeof geometry);
  Scene scene;
  scene.name = r.text("name");
  scene.positions.resize(r.count(24, "positions"));
  for (Vec3& p : scene.positions) {
    p = r.vec("positions");
    if (!isFinite(p)) r.fail("a position is not finite");
  }
  const uint64_t indices = r.count(4, "indices");
  if (indices % 3 != 0) r.fail(std::to_string(indices) + " indices, not whole triangles");
  scene.indices.resize(indices);
  std::memcpy(scene.indices.data(), r.take(indices * 4, "indices"), indices * 4);
  for (uint32_t i : scene.indices)
    if (i >= scene.positions.size()) r.fail("index " + std::to_string(i) + " past its " + std::to_string(scene.positions.size()) + " positions");
  const uint64_t closed = r.count(1, "closed flags");
  if (closed != indices / 3) r.fail("closed flags for " + std::to_string(closed) + " of " + std::to_string(indices / 3) + " triangles");
  const uint8_t* flags = r.take(closed, "closed flags");
  scene.closed.assign(flags, flags + closed);
  for (uint8_t c : scene.closed)
    if (c > 1) r.fail("a closed flag of " + std::to_string(c));
  scene.lights.resize(r.count(1 + 18 * 8 + 4, "lights"));
  for (SceneLight& l : scene.lights) {
    l.name = r.text("light name");
    const uint8_t type = r.get<uint8_t>("lights");
    if (type > uint8_t(SceneLight::Type::Unknown)) r.fail("a light of type " + std::to_string(type));
    l.type = SceneLight::Type(type);
    l.position = r.vec("lights");
    l.direction = r.vec("lights");
    l.color = r.vec("lights");
    l.innerConeDeg = r.get<double>("lights");
    l.outerConeDeg = r.get<double>("lights");
    l.range = r.get<double>("lights");
    l.edgeU = r.vec("lights");
    l.edgeV = r.vec("lights");
    if (!isFinite(l.edgeU) || !isFinite(l.edgeV)) r.fail("a light's rectangle is not finite");
  }
  scene.media.resize(r.count(4 + 8, "media"));
  for (SceneMedium& m : scene.media) {
    m.material = r.text("medium name");
    m.absorption = r.get<double>("media");
    if (!std::isfinite(m.absorption) || m.absorption < 0) r.fail("a medium's absorption is negative or not finite");
  }
  scene.meshes.resize(r.count(3 * 4 + 8 + 12, "meshes"));
  uint64_t next = 0;
  for (SceneMesh& m : scene.meshes) {
    for (std::string* name : {&m.node, &m.mesh, &m.material}) *name = r.text("mesh name");
    m.firstTriangle = r.get<uint32_t>("meshes");
    m.triangles = r.get<uint32_t>("meshes");
    for (float& c : m.transmittance) {
      c = r.get<float>("meshes");
      if (!(c >= 0 && c <= 1) || (c > 0 && c < kMinTransmittance)) r.fail("a mesh's transmittance is outside [0, 1] or subnormal");
    }
    if (m.firstTriangle != next) r.fail("a mesh starts at triangle " + std::to_string(m.firstTriangle) + ", not " + std::to_string(next));
    next += m.triangles;
  }
  if (!scene.meshes.empty() && next != indices / 3)
    r.fail("its meshes hold " + std::to_string(next) + " of " + std::to_string(indices / 3) + " triangles");
  if (r.pos != r.size) r.fail(std::to_string(r.size - r.pos) + " bytes after its end");
  if (scene.indices.empty()) r.fail("it holds no triangles");
  if (sceneHash(scene) != geometry) r.fail("its geometry does not hash to the hash it stores");
  if (s.triangles != scene.triangleCount()) r.fail("its statistics do not match its triangles");
  if (stats) *stats = s;
  return scene;
}

}  // namespace cpvs
