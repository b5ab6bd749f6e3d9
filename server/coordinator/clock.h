// Wall-clock time and random ids of the coordinator.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

namespace cpvs::server {

/// Milliseconds since the Unix epoch: what deadlines and job times are stored as.
inline int64_t nowMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

/// `prefix` and 64 bits from the system's random source, hex: ids of jobs and leases,
/// which no caller can guess.
std::string randomId(const char* prefix);

}  // namespace cpvs::server
