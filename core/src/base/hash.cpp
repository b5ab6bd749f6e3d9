#include "cpvs/base/hash.h"

#include <xxhash.h>

#include <cstdio>
#include <string>

#include "cpvs/base/error.h"

namespace cpvs {

std::string Hash128::hex() const {
  char buf[33];
  std::snprintf(buf, sizeof buf, "%016llx%016llx", static_cast<unsigned long long>(hi),
                static_cast<unsigned long long>(lo));
  return buf;
}

Hash128 contentHash(const void* data, size_t size) {
  const XXH128_hash_t h = XXH3_128bits(data, size);
  return Hash128{h.low64, h.high64};
}

Hash128 parseHashHex(const std::string& text, const std::string& what) {
  if (text.size() != 32) throw InputError(what + " '" + text + "' is not 32 hexadecimal digits");
  Hash128 h;
  for (int half = 0; half < 2; ++half) {
    uint64_t v = 0;
    for (int i = 0; i < 16; ++i) {
      const char c = text[size_t(half * 16 + i)];
      const int d = c >= '0' && c <= '9' ? c - '0' : (c >= 'a' && c <= 'f' ? c - 'a' + 10 : -1);
      if (d < 0) throw InputError(what + " '" + text + "' is not 32 lower-case hexadecimal digits");
      v = v << 4 | uint64_t(d);
    }
    (half == 0 ? h.hi : h.lo) = v;
  }
  return h;
}

}  // namespace cpvs
