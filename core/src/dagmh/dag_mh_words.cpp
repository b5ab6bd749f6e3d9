#include "cpvs/dagmh/dag_mh_words.h"

#include <cstring>

#include "cpvs/base/error.h"

namespace cpvs {

namespace {

template <class T>
void append(std::vector<uint32_t>& words, const T* data, size_t bytes) {
  const size_t at = words.size();
  words.resize(at + (bytes + 3) / 4, 0);
  if (bytes) std::memcpy(words.data() + at, data, bytes);
}

}  // namespace

std::vector<uint32_t> dagMhWords(const DagMh& dag) {
  static_assert(sizeof(ValueChunk) == 5 * 4 && sizeof(DagMhSkip) == 3 * 4);
  const uint64_t total = sizeof(DagMhWordsHeader) / 4 + dag.nodes.size() + dag.treelets.size() +
                         dag.values.chunks.size() * 5 + (dag.values.factors.size() + 3) / 4 + dag.skip.size() * 3;
  if (total > UINT32_MAX) throw InputError("a DAG-MH of " + std::to_string(total) + " words does not fit 32-bit word indices");
  if (dag.values.count > UINT32_MAX) throw InputError("a DAG-MH holds at most 2^32 - 1 values");
  std::vector<uint32_t> words(sizeof(DagMhWordsHeader) / 4, 0);
  words.reserve(total);
  DagMhWordsHeader h;
  h.log2Side = uint32_t(dag.log2Side);
  h.rootType = dag.rootType;
  h.skipLevel = uint32_t(dag.skipLevel);
  h.valueCount = uint32_t(dag.values.count);
  h.nodesWord = uint32_t(words.size());
  append(words, dag.nodes.data(), dag.nodes.size() * 4);
  h.treeletsWord = uint32_t(words.size());
  append(words, dag.treelets.data(), dag.treelets.size() * 4);
  h.chunksWord = uint32_t(words.size());
  append(words, dag.values.chunks.data(), dag.values.chunks.size() * sizeof(ValueChunk));
  h.factorsWord = uint32_t(words.size());
  append(words, dag.values.factors.data(), dag.values.factors.size());
  h.skipWord = uint32_t(words.size());
  append(words, dag.skip.data(), dag.skip.size() * sizeof(DagMhSkip));
  std::memcpy(words.data(), &h, sizeof h);
  return words;
}

}  // namespace cpvs
