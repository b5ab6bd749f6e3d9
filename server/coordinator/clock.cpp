#include "coordinator/clock.h"

#include <cstdio>
#include <mutex>
#include <random>

namespace cpvs::server {

int64_t leaseClockMs() {
  static const int64_t wallAtStart = nowMs();
  static const auto steadyAtStart = std::chrono::steady_clock::now();
  return wallAtStart +
         std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - steadyAtStart).count();
}

std::string randomId(const char* prefix) {
  // 64 bits straight from the system's source for every id (a seeded generator's next
  // ids follow from the ones it gave out): a lease id is a worker's only credential for
  // its tile.
  static std::mutex m;
  static std::random_device source;
  uint64_t v;
  {
    std::lock_guard lock(m);
    v = uint64_t(source()) << 32 | uint64_t(source());
  }
  char buf[40];
  std::snprintf(buf, sizeof buf, "%s%016llx", prefix, static_cast<unsigned long long>(v));
  return buf;
}

}  // namespace cpvs::server
