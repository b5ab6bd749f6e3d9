#include "io/bake_fields.h"

#include <algorithm>
#include <cstring>

#include "cpvs/base/text.h"
#include "cpvs/base/limits.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/light/grid_spec.h"

namespace cpvs {

void putOptions(ByteWriter& w, const BakeOptions& o, const Hash128& sceneHash) {
  w.put<uint8_t>(uint8_t(o.closed));
  w.put<uint8_t>(uint8_t(o.exit));
  w.put<uint8_t>(o.cull ? 1 : 0);
  w.put<uint8_t>(uint8_t(o.compress));
  w.put<uint8_t>(uint8_t(o.undefinedRule));
  w.put<uint8_t>(uint8_t(o.hash));
  w.put<uint8_t>(uint8_t(o.renderer));  // 0 (embree) in files written before the rasterizer
  w.put<uint8_t>(0);
  w.put<int32_t>(o.log2TileSize);
  w.put(sceneHash.lo);
  w.put(sceneHash.hi);
}

void getOptions(ByteReader& h, BakeOptions& o, Hash128& sceneHash) {
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
  sceneHash.lo = h.get<uint64_t>("header");
  sceneHash.hi = h.get<uint64_t>("header");
}

void putReceiversAndPlan(ByteWriter& w, const BakeOptions& o, const Hash128& receiverHash, const std::string& plan) {
  w.put<uint8_t>(uint8_t(o.receivers));
  w.put<uint8_t>(o.receivers == ReceiverKind::Everywhere ? 0 : o.receiverPcf);
  for (int i = 0; i < 6; ++i) w.put<uint8_t>(0);
  w.put(receiverHash.lo);
  w.put(receiverHash.hi);
  CPVS_CHECK(plan.size() <= kMaxPlanBytes);
  w.put<uint32_t>(uint32_t(plan.size()));
  for (char c : plan) w.put<uint8_t>(uint8_t(c));
}

void getReceiversAndPlan(ByteReader& h, BakeOptions& o, Hash128& receiverHash, std::string& plan) {
  const uint8_t kind = h.get<uint8_t>("receivers"), pcf = h.get<uint8_t>("receivers");
  bool reservedZero = true;
  for (int i = 0; i < 6; ++i) reservedZero = h.get<uint8_t>("receivers") == 0 && reservedZero;
  receiverHash.lo = h.get<uint64_t>("receivers");
  receiverHash.hi = h.get<uint64_t>("receivers");
  const bool everywhere = kind == uint8_t(ReceiverKind::Everywhere);
  if (!isOptionValue<ReceiverKind>(kind) || !reservedZero) h.fail("the receiver declaration holds an unknown value");
  if (everywhere ? (pcf != 0 || receiverHash != Hash128{})
                 : (pcf % 2 == 0 || pcf > kMaxPcfWidthOption || receiverHash == Hash128{}))
    h.fail("the receiver declaration is inconsistent (kind " + std::to_string(kind) + ", PCF " + std::to_string(pcf) + ")");
  o.receivers = ReceiverKind(kind);
  if (!everywhere) o.receiverPcf = pcf;
  const uint32_t planBytes = h.get<uint32_t>("plan");
  if (planBytes > kMaxPlanBytes || planBytes > h.remaining()) h.fail("the plan's size " + std::to_string(planBytes) + " is invalid");
  plan.resize(planBytes);
  for (char& c : plan) c = char(h.get<uint8_t>("plan"));
  if (validUtf8Prefix(plan, planBytes) != plan) h.fail("the plan is not UTF-8 text");
}

void putWordSection(ByteWriter& w, const std::vector<uint32_t>& words, bool zstd) {
  w.put<uint64_t>(words.size());
  std::vector<uint8_t> bytes(words.size() * 4);
  if (!words.empty()) std::memcpy(bytes.data(), words.data(), bytes.size());  // a DAG-MH may have no inner node
  writeSection(w, bytes, zstd);
}

std::vector<uint32_t> getWordSection(ByteReader& h, bool zstd, uint64_t minWords, const char* what, uint64_t maxWords) {
  const uint64_t count = h.get<uint64_t>(what);
  if (count < minWords || count > std::min<uint64_t>(maxWords, UINT32_MAX))
    h.fail(std::string(what) + " word count " + std::to_string(count) + " is invalid");
  std::vector<uint8_t> storage;
  const uint8_t* bytes = readSection(h, zstd, count * 4, what, storage);
  std::vector<uint32_t> words(count);
  if (count) std::memcpy(words.data(), bytes, count * 4);
  return words;
}

void putOrthoGrid(ByteWriter& w, const OrthoGrid& grid) {
  // The grid's description (GridSpec), its orthographic fields in their version 1 order.
  const GridSpec g = gridSpecOf(grid);
  w.putVec(g.frame.dir);
  w.putVec(g.frame.u);
  w.putVec(g.frame.v);
  w.putVec(g.origin);
  w.put(g.u0);
  w.put(g.v0);
  w.put(g.d0);
  w.put(g.extent);
  w.put(g.depthExtent);
  // The depth shift of a grid with fewer depth slices (OrthoGrid::depthShift) in the
  // resolution's second byte: a reader that predates it refuses the file's resolution
  // rather than offset its lookups as on a cubic grid.
  w.put<int32_t>(g.log2Resolution | (grid.depthShift() << 8));
}

OrthoGrid getOrthoGrid(ByteReader& h) {
  GridSpec spec;
  spec.projection = Projection::Orthographic;
  spec.frame.dir = h.getVec("header");
  spec.frame.u = h.getVec("header");
  spec.frame.v = h.getVec("header");
  spec.origin = h.getVec("header");
  spec.u0 = h.get<double>("header");
  spec.v0 = h.get<double>("header");
  spec.d0 = h.get<double>("header");
  spec.extent = h.get<double>("header");
  spec.depthExtent = h.get<double>("header");
  const int32_t resolutionField = h.get<int32_t>("header");
  spec.log2Resolution = resolutionField & 0xFF;
  const int32_t shift = resolutionField >> 8;
  if (shift != 0) {
    if (shift < 0 || shift > spec.log2Resolution)
      h.fail("the resolution field " + std::to_string(resolutionField) + " names no grid");
    // A resolution out of range is refused below (checkGrid) without its slices.
    if (spec.log2Resolution <= kMaxLog2Resolution) spec.depthSlices = uint32_t(1) << (spec.log2Resolution - shift);
  }
  try {
    return orthoGridOf(spec, h.source());
  } catch (const InputError& e) {
    throw FormatError(e.what());  // bad bytes, not a bad argument
  }
}

}  // namespace cpvs
