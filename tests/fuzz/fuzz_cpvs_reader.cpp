// libFuzzer target: the .cpvs artifact reader (the level section, the packed section and
// the light bundle's node pool), the .dmh (DAG-MH) reader, the sub-DAG reader and the
// reader of a DAG-MH tile's parts on arbitrary bytes.
// Both check a checksum first, which random bytes never pass; so every input is also
// tried with its last 8 bytes replaced by the right checksum, which lets the fuzzer
// reach the structural validation behind it. Whatever decodes is then walked.
#include <xxhash.h>

#include <cstdint>
#include <algorithm>
#include <cstring>
#include <vector>

#include "cpvs/base/error.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/io/dmh_file.h"
#include "cpvs/io/dmh_tile_file.h"
#include "cpvs/dag/packed_dag.h"
#include "cpvs/io/sub_dag_file.h"

namespace {

void walk(const cpvs::Dag& dag, const cpvs::PackedDag& packed) {
  // Every voxel of a small grid, or a sample of a large one: any read out of bounds
  // shows up under the address sanitizer. The packed words as the file held them (what
  // a GPU takes as it is) answer as the reference walk over the levels does.
  const uint64_t R = uint64_t(1) << dag.log2Resolution;
  const uint64_t step = R <= 16 ? 1 : R / 7;
  for (uint64_t x = 0; x < R; x += step)
    for (uint64_t y = 0; y < R; y += step)
      for (uint64_t z = 0; z < R; z += step)
        if (cpvs::dagVoxelShadowed(dag, x, y, z) != packed.voxelShadowed(x, y, z)) __builtin_trap();
}

void tryDecode(const uint8_t* data, size_t size) {
  try {
    cpvs::CpvsArtifact a = cpvs::decodeCpvs(data, size, "fuzz");
    walk(a.dag, a.packed);
    (void)cpvs::encodeCpvs(a, false);
  } catch (const cpvs::InputError&) {
  }
  try {
    // A bundle: every grid's view of the pool walked at a few voxels, and written again.
    const cpvs::LightBundle b = cpvs::decodeBundle(data, size, "fuzz");
    for (size_t k = 0; k < b.grids.size(); ++k) {
      const cpvs::PackedDag view = b.dag(k);
      const uint64_t R = uint64_t(1) << view.log2Resolution();
      for (uint64_t v = 0; v < R; v += R / 4 + 1) (void)view.voxelShadowed(v, R - 1 - v, v);
    }
    (void)cpvs::encodeBundle(b, false);
  } catch (const cpvs::InputError&) {
  }
  try {
    // A DAG-MH: texels and filter footprints across the map read (any word a lookup
    // follows out of place shows under the sanitizers), and written again.
    const cpvs::DmhArtifact d = cpvs::decodeDmh(data, size, "fuzz");
    const uint64_t R = uint64_t(1) << d.dag.log2Side;
    float footprint[81];
    for (uint64_t v = 0; v < R; v += R / 8 + 1) {
      (void)d.dag.depth(v, R - 1 - v);
      const uint32_t w = uint32_t(std::min<uint64_t>(9, R - v));
      d.dag.depths(v, v, w, w, footprint);
    }
    (void)cpvs::encodeDmh(d, false);
  } catch (const cpvs::InputError&) {
  }
  try {
    // A DAG-MH tile's parts (what a worker sends): each one accepted is merged into a
    // builder of its map, as the coordinator merges them.
    for (cpvs::DagMhTile& part : cpvs::decodeDagMhTiles(data, size, "fuzz")) {
      if (part.log2Side > 12) continue;  // the coordinator's builder is its job's, not the part's
      cpvs::DagMhBuilder builder(part.log2Side, part.log2TileSide);
      builder.addTile(std::move(part));
    }
  } catch (const cpvs::InputError&) {
  }
  try {
    for (bool canonical : {true, false}) {
      cpvs::Dag d = cpvs::decodeSubDag(data, size, "fuzz", canonical, cpvs::HashKind::Xxh3);
      (void)cpvs::encodeSubDag(d, false);
    }
  } catch (const cpvs::InputError&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  tryDecode(data, size);
  if (size >= 16) {
    std::vector<uint8_t> fixed(data, data + size);
    uint64_t sum = XXH3_64bits(fixed.data(), size - 8);
    std::memcpy(fixed.data() + size - 8, &sum, 8);
    tryDecode(fixed.data(), fixed.size());
  }
  return 0;
}
