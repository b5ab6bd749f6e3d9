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

/// The clock of lease deadlines, in Unix milliseconds: the wall clock as it read when the
/// process first asked, run on by the steady clock since. A step of the wall clock (NTP,
/// an operator setting the date) does not move it, so no lease expires, or outlives its
/// length, for one (R10); a restart reads the wall clock again, and gives every lease a
/// whole length (LeaseService::start).
int64_t leaseClockMs();

/// `prefix` and 64 bits from the system's random source, hex: ids of jobs and leases,
/// which no caller can guess.
std::string randomId(const char* prefix);

}  // namespace cpvs::server
