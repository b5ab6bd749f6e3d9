#include "coordinator/clock.h"

#include <cstdio>
#include <mutex>
#include <random>

namespace cpvs::server {

std::string randomId(const char* prefix) {
  // Seeded once from the system's source, then a 64-bit generator: unique and unguessable
  // enough for ids that are also checked against the store.
  static std::mutex m;
  static std::mt19937_64 rng{(uint64_t(std::random_device{}()) << 32) ^ std::random_device{}()};
  std::lock_guard lock(m);
  char buf[40];
  std::snprintf(buf, sizeof buf, "%s%016llx", prefix, static_cast<unsigned long long>(rng()));
  return buf;
}

}  // namespace cpvs::server
