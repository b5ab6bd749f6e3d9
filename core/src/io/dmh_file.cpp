#include "cpvs/io/dmh_file.h"

#include <cstring>

#include "cpvs/base/error.h"
#include "io/bake_fields.h"
#include "io/container.h"

namespace cpvs {
namespace {

constexpr ContainerKind kDmhKind{{'D', 'G', 'M', 'H'}, kDmhFormatVersion, kDmhFormatVersion, ".dmh file"};

template <class T>
void putWords(ByteWriter& w, const std::vector<T>& items, bool zstd) {
  static_assert(sizeof(T) % 4 == 0);
  std::vector<uint32_t> words(items.size() * sizeof(T) / 4);
  if (!words.empty()) std::memcpy(words.data(), items.data(), words.size() * 4);
  putWordSection(w, words, zstd);
}

// A section of exactly `count` items of T.
template <class T>
std::vector<T> getItems(ByteReader& h, bool zstd, uint64_t count, const char* what) {
  static_assert(sizeof(T) % 4 == 0);
  const std::vector<uint32_t> words = getWordSection(h, zstd, 0, what);
  if (words.size() != count * (sizeof(T) / 4))
    h.fail(std::string(what) + ": " + std::to_string(words.size()) + " words where " + std::to_string(count) +
           " entries need " + std::to_string(count * (sizeof(T) / 4)));
  std::vector<T> items(count);
  if (count) std::memcpy(static_cast<void*>(items.data()), words.data(), words.size() * 4);
  return items;
}

}  // namespace

std::vector<uint8_t> encodeDmh(const DmhArtifact& a, bool zstd) {
  const DagMh& d = a.dag;
  CPVS_CHECK(d.log2Side == a.grid.log2Resolution && a.grid.depthSlices == 0);
  ByteWriter w;
  beginContainer(w, kDmhKind, zstd ? kContainerZstd : 0);
  putOrthoGrid(w, a.grid);
  putOptions(w, a.options, a.sceneHash);
  putReceiversAndPlan(w, a.options, a.receiverHash, "");
  w.put<uint32_t>(d.rootType);
  w.put<uint32_t>(uint32_t(d.skipLevel));
  w.put<uint32_t>(kTreeletLevels);
  w.put<uint32_t>(kValuesPerChunk);
  w.put<uint64_t>(d.values.count);
  putWordSection(w, d.nodes, zstd);
  putWordSection(w, d.treelets, zstd);
  putWords(w, d.values.chunks, zstd);
  w.put<uint64_t>(d.values.factors.size());
  writeSection(w, d.values.factors, zstd);
  putWords(w, d.skip, zstd);
  return sealContainer(std::move(w));
}

bool isDmh(const uint8_t* data, size_t size) { return size >= 4 && std::memcmp(data, kDmhKind.magic, 4) == 0; }

DmhArtifact decodeDmh(const uint8_t* data, size_t size, const std::string& source) {
  uint32_t flags = 0, version = 0;
  ByteReader h = openContainer(data, size, source, kDmhKind, kContainerZstd, flags, version);
  const bool zstd = (flags & kContainerZstd) != 0;
  DmhArtifact a;
  a.grid = getOrthoGrid(h);
  if (a.grid.depthSlices != 0) h.fail("a DAG-MH on a grid of " + std::to_string(a.grid.depthSlices) + " depth slices");
  getOptions(h, a.options, a.sceneHash);
  std::string plan;
  getReceiversAndPlan(h, a.options, a.receiverHash, plan);
  DagMh& d = a.dag;
  d.log2Side = a.grid.log2Resolution;
  d.rootType = h.get<uint32_t>("header");
  const uint32_t skipLevel = h.get<uint32_t>("header");
  if (skipLevel > uint32_t(kDagMhSkipLevel)) h.fail("skip level " + std::to_string(skipLevel));
  d.skipLevel = int(skipLevel);
  const uint32_t treeletLevels = h.get<uint32_t>("header"), perChunk = h.get<uint32_t>("header");
  if (treeletLevels != uint32_t(kTreeletLevels) || perChunk != kValuesPerChunk)
    h.fail("treelets of " + std::to_string(treeletLevels) + " levels and chunks of " + std::to_string(perChunk) +
           " values (this reader knows 4 and 32)");
  d.values.count = h.get<uint64_t>("header");
  if (d.values.count > UINT32_MAX) h.fail("value count " + std::to_string(d.values.count));
  d.nodes = getWordSection(h, zstd, 0, "inner nodes");
  d.treelets = getWordSection(h, zstd, 0, "treelets");
  d.values.chunks = getItems<ValueChunk>(h, zstd, (d.values.count + kValuesPerChunk - 1) / kValuesPerChunk, "value chunks");
  const uint64_t factorBytes = h.get<uint64_t>("header");
  if (factorBytes < kFactorStreamPadding || factorBytes > kMaxFactorStreamBytes + 64)
    h.fail("factor stream of " + std::to_string(factorBytes) + " bytes");
  std::vector<uint8_t> storage;
  const uint8_t* factors = readSection(h, zstd, factorBytes, "factor stream", storage);
  d.values.factors.assign(factors, factors + factorBytes);
  const uint64_t entries = d.skipLevel > 0 ? uint64_t(1) << (2 * d.skipLevel) : 0;
  d.skip = getItems<DagMhSkip>(h, zstd, entries, "skip list");
  if (h.remaining() != 0) h.fail(std::to_string(h.remaining()) + " unexpected bytes after the payload");
  validateDagMh(d, source);
  return a;
}

}  // namespace cpvs
