#include "cpvs/base/error.h"

#include <cstdio>
#include <cstdlib>

namespace cpvs::detail {

void checkFailed(const char* expr, const char* file, int line) {
  std::fprintf(stderr, "%s:%d: check failed: %s\n", file, line, expr);
  std::fflush(stderr);
  std::abort();
}

}  // namespace cpvs::detail
