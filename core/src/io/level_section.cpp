#include "io/level_section.h"

#include "io/container.h"

#include <bit>
#include <limits>

namespace cpvs {

namespace {

size_t pad4(size_t n) { return (n + 3) & ~size_t(3); }

}  // namespace

void writeDagLevels(const Dag& dag, bool zstd, ByteWriter& w) {
  ByteWriter payload;
  payload.raw(dag.leaves.data(), dag.leaves.size() * 8);
  for (const auto& lv : dag.levels) {
    payload.raw(lv.codes.data(), lv.codes.size() * 2);
    if (lv.codes.size() % 2) payload.put<uint16_t>(0);
    payload.raw(lv.children.data(), lv.children.size() * 4);
  }
  w.put<uint32_t>(uint32_t(dag.levels.size()));
  w.put<uint64_t>(dag.leaves.size());
  for (const auto& lv : dag.levels) {
    w.put<uint64_t>(lv.size());
    w.put<uint64_t>(lv.children.size());
  }
  writeSection(w, payload.bytes, zstd);
}

void readDagLevels(ByteReader& h, bool zstd, int expectedLevels, Dag& dag) {
  uint32_t levels = h.get<uint32_t>("level table");
  if (int64_t(levels) != expectedLevels)
    h.fail(std::to_string(levels) + " levels where " + std::to_string(expectedLevels) + " were expected");
  uint64_t leafCount = h.get<uint64_t>("level table");
  std::vector<uint64_t> nodeCounts(levels), childCounts(levels);
  uint64_t expected = 0;
  constexpr uint64_t kMaxCount = std::numeric_limits<uint32_t>::max();
  if (leafCount > kMaxCount) h.fail("leaf count is out of range");
  expected += leafCount * 8;
  for (uint32_t l = 0; l < levels; ++l) {
    nodeCounts[l] = h.get<uint64_t>("level table");
    childCounts[l] = h.get<uint64_t>("level table");
    // Child offsets (childBegin) are 32-bit: more references than that would wrap.
    if (nodeCounts[l] > kMaxCount || childCounts[l] > kMaxCount || childCounts[l] > 8 * nodeCounts[l])
      h.fail("level " + std::to_string(l) + " sizes are out of range");
    expected += pad4(nodeCounts[l] * 2) + childCounts[l] * 4;
  }
  std::vector<uint8_t> unpacked;
  const uint8_t* payload = readSection(h, zstd, expected, "payload", unpacked);
  ByteReader p(payload, expected, h.source());
  dag.leaves.resize(leafCount);
  p.copy(dag.leaves.data(), leafCount * 8, "leaves");
  for (uint32_t l = 0; l < levels; ++l) {
    InternalLevel& lv = dag.levels[l];
    lv.codes.resize(nodeCounts[l]);
    p.copy(lv.codes.data(), nodeCounts[l] * 2, "node codes");
    if (nodeCounts[l] % 2) p.take(2, "node codes");
    lv.children.resize(childCounts[l]);
    p.copy(lv.children.data(), childCounts[l] * 4, "child indices");
    // Codes and child indices are checked against the level below before any use.
    uint64_t below = l == 0 ? leafCount : nodeCounts[l - 1];
    lv.childBegin.resize(nodeCounts[l] + 1);
    uint64_t at = 0;
    for (uint64_t i = 0; i < nodeCounts[l]; ++i) {
      lv.childBegin[i] = uint32_t(at);
      uint16_t c = lv.codes[i];
      if (!validCodes(c))
        p.fail("level " + std::to_string(l) + " node " + std::to_string(i) + " has an invalid child code");
      at += uint64_t(refCount(c));
      if (at > childCounts[l]) p.fail("level " + std::to_string(l) + " holds more references than indices");
    }
    if (at != childCounts[l]) p.fail("level " + std::to_string(l) + " reference count does not match");
    lv.childBegin[nodeCounts[l]] = uint32_t(at);
    for (uint64_t k = 0; k < childCounts[l]; ++k)
      if (lv.children[k] >= below)
        p.fail("level " + std::to_string(l) + " child index " + std::to_string(lv.children[k]) +
               " is out of range (" + std::to_string(below) + " nodes below)");
  }
}

}  // namespace cpvs
