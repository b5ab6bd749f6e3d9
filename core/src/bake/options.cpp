#include "cpvs/bake/options.h"

#include <bit>

#include "cpvs/base/error.h"

namespace cpvs {

void throwUnknownOption(const std::string& what, std::string_view name, const std::string& accepted) {
  throw InputError(what + ": '" + std::string(name) + "' is not one of " + accepted);
}

int log2TileSizeOf(uint64_t texels, const std::string& what) {
  constexpr uint64_t lo = uint64_t(1) << kMinLog2TileSize, hi = uint64_t(1) << kMaxLog2TileSize;
  if (texels < lo || texels > hi || !std::has_single_bit(texels))
    throw InputError(what + " " + std::to_string(texels) + " must be a power of two in " + std::to_string(lo) +
                     ".." + std::to_string(hi));
  return std::countr_zero(texels);
}

std::string describe(const BakeOptions& o) {
  return std::string("closed ") + optionName(o.closed) + ", exit " + optionName(o.exit) + ", cull " +
         (o.cull ? "on" : "off") + ", compress " + optionName(o.compress) + ", undefined " +
         optionName(o.undefinedRule) + ", renderer " + optionName(o.renderer) + ", tile " + std::to_string(uint64_t(1) << o.log2TileSize) +
         (o.hash == HashKind::Xxh3 ? "" : std::string(", hash ") + optionName(o.hash));
}

}  // namespace cpvs
