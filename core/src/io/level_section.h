// The level section shared by the .cpvs artifact and the sub-DAG files that workers send:
// level table, then the levels as one container section (optionally zstd), every count
// and child index validated on the way in. Private to io.
#pragma once

#include <cstdint>

#include "cpvs/dag/dag.h"
#include "io/byte_io.h"

namespace cpvs {

/// Writes the DAG's level section: level count, leaf count, node and reference counts
/// per level, payload size, stored size, then the payload (leaves; per level the 16-bit
/// codes padded to 4 bytes and the 32-bit child indices), zstd-compressed when asked.
void writeDagLevels(const Dag& dag, bool zstd, ByteWriter& w);

/// Reads a level section into `dag` (reset by the caller to `expectedLevels` levels),
/// checking every size against the data present, every child code, and every child index
/// against the level below. Throws InputError through `r` on any mismatch.
void readDagLevels(ByteReader& r, bool zstd, int expectedLevels, Dag& dag);

}  // namespace cpvs
