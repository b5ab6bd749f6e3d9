#include "cpvs/io/bundle_file.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "cpvs/base/error.h"
#include "cpvs/base/limits.h"
#include "cpvs/base/text.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/light/grid_spec.h"
#include "io/bake_fields.h"
#include "io/container.h"

namespace cpvs {

uint64_t LightBundle::lightBytes(size_t light) const {
  const BundleLight& l = lights.at(light);
  uint64_t b = 0;
  for (uint32_t k = l.firstGrid; k < l.firstGrid + l.gridCount; ++k) b += grids[k].bytes;
  return b;
}

LightBundle withPointerGrids(const LightBundle& bundle, int levels) {
  if (levels < 0 || levels > kMaxGridLevels)
    throw InputError("pointer grid levels " + std::to_string(levels) + " outside [0, " + std::to_string(kMaxGridLevels) + "]");
  NodePool pool = parsePackedPool(*bundle.pool, bundle.grids.size());
  for (NodePool::Root& r : pool.roots) r.gridLevels = std::min(levels, packedGridLevels(r.log2Resolution));
  LightBundle b = bundle;
  // In today's layout (a pool of an older one, built in memory, is packed again), and its
  // bytes counted in it.
  b.pool = std::make_shared<const std::vector<uint32_t>>(packPool(pool.leaves, pool.levels, pool.roots));
  for (size_t k = 0; k < b.grids.size(); ++k) b.grids[k].bytes = reachableBytes(pool, k);
  b.poolBytes = pool.bytes();
  return b;
}

std::vector<uint8_t> encodeBundle(const LightBundle& b, bool zstd) {
  CPVS_CHECK(!b.lights.empty() && b.pool);
  ByteWriter w;
  beginContainer(w, kCpvsKind, zstd ? kContainerZstd : 0);
  putOptions(w, b.options, b.sceneHash);
  putReceiversAndPlan(w, b.options, b.receiverHash, b.plan);
  w.put<uint32_t>(uint32_t(b.lights.size()));
  w.put<uint32_t>(uint32_t(b.grids.size()));
  for (const BundleLight& bl : b.lights) {
    const Light& l = bl.light;
    w.put<uint8_t>(uint8_t(l.kind));
    w.put<uint16_t>(uint16_t(l.area));  // 0 before area lights: older bundles read as they were
    for (int i = 0; i < 5; ++i) w.put<uint8_t>(0);
    w.putVec(l.position);
    w.putVec(l.direction);
    w.put(l.coneDeg);
    w.put(l.range);
    w.putVec(l.colour);
    w.put(l.intensity);
    w.put(l.near);
    w.put<int32_t>(l.log2Resolution);
    w.put<uint32_t>(bl.firstGrid);
    w.put<uint32_t>(bl.gridCount);
    CPVS_CHECK(l.name.size() <= kMaxLightNameBytes);
    w.put<uint16_t>(uint16_t(l.name.size()));
    w.raw(l.name.data(), l.name.size());
  }
  for (const BundleGrid& bg : b.grids) {
    const GridSpec g = gridSpecOf(bg.grid, bg.tanCone);
    w.putVec(g.frame.dir);
    w.putVec(g.frame.u);
    w.putVec(g.frame.v);
    w.put(g.tanHalfFov);
    w.put(g.tanCone);
    w.put(g.near);
    w.put(g.far);
    w.put<int32_t>(g.log2Resolution);
    w.put<uint32_t>(bg.light);
    w.put<uint64_t>(bg.bytes);
  }
  putWordSection(w, *b.pool, zstd);
  return sealContainer(std::move(w));
}

LightBundle decodeBundle(const uint8_t* data, size_t size, const std::string& source) {
  uint32_t flags = 0, version = 0;
  ByteReader h = openContainer(data, size, source, kCpvsKind, kContainerZstd, flags, version);
  if (version != kBundleFormatVersion)
    h.fail("a sun artifact (format " + std::to_string(version) + "), not a light bundle");
  LightBundle b;
  getOptions(h, b.options, b.sceneHash);
  getReceiversAndPlan(h, b.options, b.receiverHash, b.plan);
  const uint32_t lightCount = h.get<uint32_t>("light table"), gridCount = h.get<uint32_t>("light table");
  if (lightCount == 0 || lightCount > kMaxLights)
    h.fail("the light count " + std::to_string(lightCount) + " is outside [1, " + std::to_string(kMaxLights) + "]");
  if (gridCount < lightCount || gridCount > 6 * uint64_t(lightCount))
    h.fail("the grid count " + std::to_string(gridCount) + " does not fit " + std::to_string(lightCount) + " lights");
  uint32_t nextGrid = 0;
  for (uint32_t i = 0; i < lightCount; ++i) {
    BundleLight bl;
    Light& l = bl.light;
    const std::string label = "light " + std::to_string(i);
    const uint8_t kind = h.get<uint8_t>("light table");
    l.area = h.get<uint16_t>("light table");
    bool reservedZero = true;
    for (int k = 0; k < 5; ++k) reservedZero = h.get<uint8_t>("light table") == 0 && reservedZero;
    if (kind > uint8_t(LightKind::Point) || !reservedZero) h.fail(label + " holds an unknown kind");
    l.kind = LightKind(kind);
    l.position = h.getVec("light table");
    l.direction = h.getVec("light table");
    l.coneDeg = h.get<double>("light table");
    l.range = h.get<double>("light table");
    l.colour = h.getVec("light table");
    l.intensity = h.get<double>("light table");
    l.near = h.get<double>("light table");
    l.log2Resolution = h.get<int32_t>("light table");
    bl.firstGrid = h.get<uint32_t>("light table");
    bl.gridCount = h.get<uint32_t>("light table");
    const uint16_t nameBytes = h.get<uint16_t>("light table");
    if (nameBytes > kMaxLightNameBytes) h.fail(label + "'s name is longer than " + std::to_string(kMaxLightNameBytes) + " bytes");
    l.name.resize(nameBytes);
    h.copy(l.name.data(), nameBytes, "light table");
    if (validUtf8Prefix(l.name, nameBytes) != l.name) h.fail(label + "'s name is not UTF-8 text");
    try {
      checkLight(l, l.position, l.position, label);  // the bounds are the scene's, not stored
    } catch (const InputError& e) {
      h.fail(e.what());
    }
    const uint32_t grids = l.kind == LightKind::Spot ? 1 : 6;
    if (bl.firstGrid != nextGrid || bl.gridCount != grids)
      h.fail(label + "'s grids " + std::to_string(bl.firstGrid) + " + " + std::to_string(bl.gridCount) +
             " do not follow the ones before (a " + lightKindName(l.kind) + " light has " + std::to_string(grids) + ")");
    nextGrid += grids;
    b.lights.push_back(std::move(bl));
  }
  // Area lights are numbered 1, 2, ... in their VPLs: none without one.
  uint32_t areas = 0;
  for (const BundleLight& bl : b.lights) areas = std::max<uint32_t>(areas, bl.light.area);
  std::vector<uint8_t> hasVpl(size_t(areas) + 1, 0);
  for (const BundleLight& bl : b.lights) hasVpl[bl.light.area] = 1;
  for (uint32_t a = 1; a <= areas; ++a)
    if (!hasVpl[a]) h.fail("area light " + std::to_string(a) + " has no VPL (the numbers must run from 1)");
  // And each one's VPLs are consecutive lights (a soft lookup walks them from the first).
  std::vector<uint8_t> ended(size_t(areas) + 1, 0);
  for (size_t i = 0; i < b.lights.size(); ++i) {
    const uint32_t a = b.lights[i].light.area;
    if (a != 0 && ended[a]) h.fail("area light " + std::to_string(a) + "'s VPLs are not consecutive lights");
    if (i > 0 && b.lights[i - 1].light.area != a) ended[b.lights[i - 1].light.area] = 1;
  }
  if (nextGrid != gridCount) h.fail("the lights have " + std::to_string(nextGrid) + " grids, the table " + std::to_string(gridCount));
  uint64_t slices = 0;
  for (uint32_t k = 0; k < gridCount; ++k) {
    const std::string label = "grid " + std::to_string(k);
    // A grid's apex is its light's position (the light table's).
    GridSpec g;
    g.projection = Projection::Perspective;
    g.frame.dir = h.getVec("grid table");
    g.frame.u = h.getVec("grid table");
    g.frame.v = h.getVec("grid table");
    g.tanHalfFov = h.get<double>("grid table");
    g.tanCone = h.get<double>("grid table");
    g.near = h.get<double>("grid table");
    g.far = h.get<double>("grid table");
    g.log2Resolution = h.get<int32_t>("grid table");
    const uint32_t light = h.get<uint32_t>("grid table");
    const uint64_t bytes = h.get<uint64_t>("grid table");
    if (light >= lightCount || k < b.lights[light].firstGrid || k >= b.lights[light].firstGrid + b.lights[light].gridCount)
      h.fail(label + " names light " + std::to_string(light) + ", which does not hold it");
    g.position = b.lights[light].light.position;
    if (g.log2Resolution >= kMinLog2Resolution && g.log2Resolution <= kMaxLog2Resolution)
      slices += g.resolution() + 1;
    if (slices > kMaxBundleSlices)
      h.fail("the grids hold more than " + std::to_string(kMaxBundleSlices) + " slice boundaries together");
    try {
      b.grids.push_back({perspectiveGridOf(g, label), g.tanCone, light, bytes});
    } catch (const InputError& e) {
      h.fail(e.what());
    }
  }

  // A point light's cube is its faces' axes (+x, +y, +z faces), a rolled VPL's turned.
  for (size_t i = 0; i < b.lights.size(); ++i) {
    BundleLight& bl = b.lights[i];
    if (bl.light.kind != LightKind::Point) continue;
    const auto dir = [&](int face) { return b.grids[bl.firstGrid + face].grid.frame().dir; };
    bl.light.cube = {dir(0), dir(2), dir(4)};
    bool opposite = true;
    for (int axis = 0; axis < 3; ++axis) opposite = opposite && dir(2 * axis + 1) == withoutNegativeZeros(-dir(2 * axis));
    if (!opposite || !isOrthonormalCube(bl.light.cube))
      h.fail("light " + std::to_string(i) + "'s six grids are not a cube's faces");
  }

  const bool zstd = (flags & kContainerZstd) != 0;
  std::vector<uint32_t> words = getWordSection(h, zstd, uint64_t(kPackedHeaderWords) * gridCount, "node pool");
  if (h.remaining() != 0) h.fail(std::to_string(h.remaining()) + " unexpected bytes after the payload");
  NodePool pool;
  try {
    pool = parsePackedPool(words, gridCount);
  } catch (const InputError& e) {
    h.fail(e.what());
  }
  for (uint32_t k = 0; k < gridCount; ++k) {
    if (pool.roots[k].log2Resolution != b.grids[k].grid.log2Resolution())
      h.fail("grid " + std::to_string(k) + "'s DAG is of resolution 2^" + std::to_string(pool.roots[k].log2Resolution) +
             ", the grid of 2^" + std::to_string(b.grids[k].grid.log2Resolution()));
    // In the words' own layout: an older bundle recorded its bytes in its layout.
    const uint64_t held = reachableBytes(pool, k, packedLayoutVersion(words));
    if (held != b.grids[k].bytes)
      h.fail("grid " + std::to_string(k) + " records " + std::to_string(b.grids[k].bytes) + " bytes, its DAG holds " +
             std::to_string(held));
  }
  if (packedLayoutVersion(words) < kPackedLayoutVersion) {  // walked in today's layout
    try {
      words = packPool(pool.leaves, pool.levels, pool.roots);
    } catch (const InputError& e) {
      h.fail(e.what());
    }
    for (uint32_t k = 0; k < gridCount; ++k) b.grids[k].bytes = reachableBytes(pool, k);
  }
  b.poolBytes = pool.bytes();
  b.pool = std::make_shared<const std::vector<uint32_t>>(std::move(words));
  return b;
}

}  // namespace cpvs
