#include "cpvs/io/cpvs_file.h"

#include "cpvs/base/error.h"
#include "cpvs/base/text.h"

#include "io/container.h"
#include "io/level_section.h"

#include <cmath>
#include <cstring>
#include <string>

namespace cpvs {

namespace {

constexpr ContainerKind kCpvsKind{{'C', 'P', 'V', 'S'}, kCpvsFormatVersion, kCpvsOldestFormatVersion, ".cpvs file"};

}  // namespace

std::vector<uint8_t> encodeCpvs(const CpvsArtifact& a, bool zstd) {
  const Dag& dag = a.dag;
  CPVS_CHECK(dag.roots.size() == 1 && dag.log2RootSize == dag.log2Resolution);
  ByteWriter w;
  beginContainer(w, kCpvsKind, zstd ? kContainerZstd : 0);
  const OrthoGrid& g = a.grid;
  w.putVec(g.frame.dir);
  w.putVec(g.frame.u);
  w.putVec(g.frame.v);
  w.putVec(g.origin);
  w.put(g.u0);
  w.put(g.v0);
  w.put(g.d0);
  w.put(g.extent);
  w.put(g.depthExtent);
  w.put<int32_t>(g.log2Resolution);
  const BakeOptions& o = a.options;
  w.put<uint8_t>(uint8_t(o.closed));
  w.put<uint8_t>(uint8_t(o.exit));
  w.put<uint8_t>(o.cull ? 1 : 0);
  w.put<uint8_t>(uint8_t(o.compress));
  w.put<uint8_t>(uint8_t(o.undefinedRule));
  w.put<uint8_t>(uint8_t(o.hash));
  w.put<uint8_t>(uint8_t(o.renderer));  // 0 (embree) in files written before the rasterizer
  w.put<uint8_t>(0);
  w.put<int32_t>(o.log2TileSize);
  w.put(a.sceneHash.lo);
  w.put(a.sceneHash.hi);
  w.put<uint8_t>(uint8_t(o.receivers));
  w.put<uint8_t>(o.receivers == ReceiverKind::Everywhere ? 0 : o.receiverPcf);
  for (int i = 0; i < 6; ++i) w.put<uint8_t>(0);
  w.put(a.receiverHash.lo);
  w.put(a.receiverHash.hi);
  CPVS_CHECK(a.plan.size() <= kMaxPlanBytes);
  w.put<uint32_t>(uint32_t(a.plan.size()));
  for (char c : a.plan) w.put<uint8_t>(uint8_t(c));
  const PackedDag packed(dag);
  const std::vector<uint32_t>& words = packed.words();
  w.put<uint64_t>(words.size());
  std::vector<uint8_t> bytes(words.size() * 4);
  std::memcpy(bytes.data(), words.data(), bytes.size());
  writeSection(w, bytes, zstd);
  return sealContainer(std::move(w));
}

CpvsArtifact decodeCpvs(const uint8_t* data, size_t size, const std::string& source) {
  uint32_t flags = 0, version = 0;
  ByteReader h = openContainer(data, size, source, kCpvsKind, kContainerZstd, flags, version);

  CpvsArtifact a;
  a.formatVersion = version;
  OrthoGrid& g = a.grid;
  g.frame.dir = h.getVec("header");
  g.frame.u = h.getVec("header");
  g.frame.v = h.getVec("header");
  g.origin = h.getVec("header");
  g.u0 = h.get<double>("header");
  g.v0 = h.get<double>("header");
  g.d0 = h.get<double>("header");
  g.extent = h.get<double>("header");
  g.depthExtent = h.get<double>("header");
  g.log2Resolution = h.get<int32_t>("header");
  try {
    checkGrid(g, source);
  } catch (const InputError& e) {
    throw FormatError(e.what());  // bad bytes, not a bad argument
  }

  BakeOptions& o = a.options;
  uint8_t opt[6];
  for (auto& b : opt) b = h.get<uint8_t>("options");
  if (!isOptionValue<ClosedMode>(opt[0]) || !isOptionValue<ExitMode>(opt[1]) || opt[2] > 1 ||
      !isOptionValue<CompressMode>(opt[3]) || !isOptionValue<UndefinedRule>(opt[4]) || !isOptionValue<HashKind>(opt[5]))
    h.fail("options hold an unknown value");
  o.closed = ClosedMode(opt[0]);
  o.exit = ExitMode(opt[1]);
  o.cull = opt[2] != 0;
  o.compress = CompressMode(opt[3]);
  o.undefinedRule = UndefinedRule(opt[4]);
  o.hash = HashKind(opt[5]);
  const uint8_t renderer = h.get<uint8_t>("options");
  if (!isOptionValue<Renderer>(renderer) || h.get<uint8_t>("options") != 0) h.fail("options hold an unknown value");
  o.renderer = Renderer(renderer);
  o.log2TileSize = h.get<int32_t>("options");
  if (o.log2TileSize < kMinLog2TileSize || o.log2TileSize > kMaxLog2TileSize)
    h.fail("tile size 2^" + std::to_string(o.log2TileSize) + " is out of range");
  a.sceneHash.lo = h.get<uint64_t>("header");
  a.sceneHash.hi = h.get<uint64_t>("header");
  if (version >= 3) {
    const uint8_t kind = h.get<uint8_t>("receivers"), pcf = h.get<uint8_t>("receivers");
    bool reservedZero = true;
    for (int i = 0; i < 6; ++i) reservedZero = h.get<uint8_t>("receivers") == 0 && reservedZero;
    a.receiverHash.lo = h.get<uint64_t>("receivers");
    a.receiverHash.hi = h.get<uint64_t>("receivers");
    const bool everywhere = kind == uint8_t(ReceiverKind::Everywhere);
    if (!isOptionValue<ReceiverKind>(kind) || !reservedZero)
      h.fail("the receiver declaration holds an unknown value");
    if (everywhere ? (pcf != 0 || a.receiverHash != Hash128{}) : (pcf % 2 == 0 || pcf > kMaxPcfWidthOption || a.receiverHash == Hash128{}))
      h.fail("the receiver declaration is inconsistent (kind " + std::to_string(kind) + ", PCF " + std::to_string(pcf) + ")");
    o.receivers = ReceiverKind(kind);
    if (!everywhere) o.receiverPcf = pcf;
    const uint32_t planBytes = h.get<uint32_t>("plan");
    if (planBytes > kMaxPlanBytes || planBytes > h.remaining())
      h.fail("the plan's size " + std::to_string(planBytes) + " is invalid");
    a.plan.resize(planBytes);
    for (char& c : a.plan) c = char(h.get<uint8_t>("plan"));
    if (validUtf8Prefix(a.plan, planBytes) != a.plan) h.fail("the plan is not UTF-8 text");
  }

  const bool zstd = (flags & kContainerZstd) != 0;
  if (version >= 2) {
    const uint64_t count = h.get<uint64_t>("packed DAG");
    if (count < kPackedHeaderWords || count > UINT32_MAX) h.fail("packed DAG word count " + std::to_string(count) + " is invalid");
    std::vector<uint8_t> storage;
    const uint8_t* bytes = readSection(h, zstd, count * 4, "packed DAG", storage);
    std::vector<uint32_t> words(count);
    std::memcpy(words.data(), bytes, count * 4);
    if (h.remaining() != 0) h.fail(std::to_string(h.remaining()) + " unexpected bytes after the payload");
    if (words[1] != uint32_t(g.log2Resolution))
      h.fail("the packed DAG is of resolution 2^" + std::to_string(words[1]) + ", the grid of 2^" + std::to_string(g.log2Resolution));
    try {
      a.packed = PackedDag::fromWords(std::move(words), a.dag);
    } catch (const InputError& e) {
      h.fail(e.what());
    }
    return a;
  }
  Dag& dag = a.dag;
  NodeRef root;
  root.code = h.get<uint32_t>("root");
  root.index = h.get<uint32_t>("root");
  const int levels = Dag::internalLevels(g.log2Resolution);
  dag.reset(g.log2Resolution, g.log2Resolution);
  readDagLevels(h, zstd, levels, dag);
  if (h.remaining() != 0) h.fail(std::to_string(h.remaining()) + " unexpected bytes after the payload");
  uint64_t top = levels == 0 ? dag.leaves.size() : dag.levels[levels - 1].size();
  if (root.code > kRef || (root.code == kRef && root.index >= top)) h.fail("root reference is invalid");
  dag.roots.push_back(Dag::Root{0, root});
  a.packed = PackedDag(dag);
  return a;
}

}  // namespace cpvs
