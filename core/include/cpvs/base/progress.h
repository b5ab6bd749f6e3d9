// Progress and cancellation of long work, and wall-clock timing.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>

namespace cpvs {

/// Progress of long work: stage name, units done, units total. Return false to cancel;
/// the work then throws Cancelled (base/error.h) at its next check. Called from the
/// thread that runs the work, never concurrently.
using ProgressFn = std::function<bool(const std::string& stage, uint64_t done, uint64_t total)>;

/// Seconds since `start`, for stage timing.
inline double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace cpvs
