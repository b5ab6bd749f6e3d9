// A TOP tree as a container section (an artifact's translucent casters): the light, the
// origin and margins, the node count, then the 32-byte nodes and each frustum's RGB
// transmittance as one section (optionally zstd): the bytes a GPU buffer holds. Private
// to io.
#pragma once

#include "cpvs/psv/top_tree.h"
#include "io/byte_io.h"

namespace cpvs {

void writeTopTree(const TopTree& tree, bool zstd, ByteWriter& w);
/// Validated as TopTree::fromNodes validates; FormatError through `r` otherwise.
TopTree readTopTree(ByteReader& r, bool zstd);

}  // namespace cpvs
