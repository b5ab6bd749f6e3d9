// 128-bit content hashes: nodes, scenes and jobs are named by what they hold.
#pragma once

#include <compare>
#include <cstddef>
#include <cstdint>
#include <string>

namespace cpvs {

/// A 128-bit content hash (XXH3-128 in production). Ordered so that DAG levels can be
/// sorted by it.
struct Hash128 {
  uint64_t lo = 0, hi = 0;
  constexpr auto operator<=>(const Hash128& o) const {
    if (auto c = hi <=> o.hi; c != 0) return c;
    return lo <=> o.lo;
  }
  constexpr bool operator==(const Hash128&) const = default;
  std::string hex() const;
};

/// XXH3-128 of bytes: the content address of uploaded scenes, tile results and artifacts.
Hash128 contentHash(const void* data, size_t size);

/// A 32-hex-digit content hash, lower case (what hex() writes); InputError naming `what`
/// for anything else.
Hash128 parseHashHex(const std::string& text, const std::string& what);

}  // namespace cpvs
