#include "io/top_section.h"

#include <cstring>

#include "cpvs/base/error.h"
#include "io/container.h"

namespace cpvs {
namespace {

/// Frusta a section may hold: 2^27 (a 16 GiB tree) is far past any translucent set.
constexpr uint64_t kMaxStoredFrusta = uint64_t(1) << 27;
constexpr size_t kTransmittanceBytes = 3 * sizeof(float);

}  // namespace

void writeTopTree(const TopTree& tree, bool zstd, ByteWriter& w) {
  CPVS_CHECK(tree.linked() && tree.transmittance().size() == tree.frustumCount());
  w.put<uint8_t>(tree.light().directional ? 1 : 0);
  for (int i = 0; i < 7; ++i) w.put<uint8_t>(0);
  w.putVec(tree.light().vector);
  w.putVec(tree.origin());
  w.put(tree.buildTolerance());
  w.put(tree.queryMargin());
  const uint64_t frusta = tree.frustumCount();
  w.put(frusta);
  std::vector<uint8_t> bytes(tree.bytes() + frusta * kTransmittanceBytes);
  std::memcpy(bytes.data(), tree.nodes().data(), tree.bytes());
  if (frusta) std::memcpy(bytes.data() + tree.bytes(), tree.transmittance().data(), frusta * kTransmittanceBytes);
  writeSection(w, bytes, zstd);
}

TopTree readTopTree(ByteReader& r, bool zstd) {
  const uint8_t directional = r.get<uint8_t>("translucent casters");
  if (directional > 1) r.fail("translucent casters: a light kind of " + std::to_string(directional));
  for (int i = 0; i < 7; ++i)
    if (r.get<uint8_t>("translucent casters") != 0) r.fail("translucent casters: reserved bytes are not zero");
  PsvLight light;
  light.directional = directional == 1;
  light.vector = r.getVec("translucent casters");
  const Vec3 origin = r.getVec("translucent casters");
  const double tolerance = r.get<double>("translucent casters");
  const double margin = r.get<double>("translucent casters");
  const uint64_t frusta = r.get<uint64_t>("translucent casters");
  if (frusta > kMaxStoredFrusta) r.fail("translucent casters: " + std::to_string(frusta) + " frusta, more than any tree holds");
  const uint64_t nodeBytes = (4 * frusta + 1) * sizeof(TopNode);
  std::vector<uint8_t> storage;
  const uint8_t* bytes = readSection(r, zstd, nodeBytes + frusta * kTransmittanceBytes, "translucent casters", storage);
  std::vector<TopNode> nodes(4 * frusta + 1);
  std::memcpy(nodes.data(), bytes, nodeBytes);
  std::vector<std::array<float, 3>> transmittance(frusta);
  if (frusta) std::memcpy(transmittance.data(), bytes + nodeBytes, frusta * kTransmittanceBytes);
  try {
    return TopTree::fromNodes(std::move(nodes), light, origin, tolerance, margin, std::move(transmittance));
  } catch (const InputError& e) {
    r.fail(e.what());
  }
}

}  // namespace cpvs
