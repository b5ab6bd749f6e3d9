// A DAG-MH as one array of 32-bit words, what a GPU binds: a header, then its sections as
// the .dmh file holds them (inner nodes, treelets, chunks, the factor stream, the skip
// list), each at a word offset the header names. cpvs_shadow.glsl's CPVS_DAG_MH section
// reads exactly these words (its constants are generated from this header).
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/dagmh/dag_mh.h"

namespace cpvs {

/// "DGMW": the words are a DAG-MH's.
constexpr uint32_t kDagMhWordsMagic = 0x574D4744u;

/// Word 0 onwards of the array. Offsets are in words from the array's start.
struct DagMhWordsHeader {
  uint32_t magic = kDagMhWordsMagic;
  uint32_t log2Side = 0;
  uint32_t rootType = 0;   // DagMhChild of the root
  uint32_t skipLevel = 0;  // 0: no skip list
  uint32_t nodesWord = 0;
  uint32_t treeletsWord = 0;
  uint32_t chunksWord = 0;   // 5 words a ValueChunk
  uint32_t factorsWord = 0;  // the factor stream, little-endian, its padding included
  uint32_t skipWord = 0;     // 3 words a DagMhSkip
  uint32_t valueCount = 0;
  uint32_t reserved[6] = {};
};
static_assert(sizeof(DagMhWordsHeader) == 64);

/// The array (InputError when it would exceed 2^32 - 1 words).
std::vector<uint32_t> dagMhWords(const DagMh& dag);

}  // namespace cpvs
