// Progress and cancellation of long work, and wall-clock timing.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>

namespace cpvs {

/// How far long work is: units done of the total, and the seconds the work expects it
/// still needs when it can say better than done/total would (its units cost unlike
/// amounts: a bake's tiles hold unlike numbers of triangles); negative when it cannot.
struct Progress {
  std::string stage;
  uint64_t done = 0, total = 0;
  double secondsLeft = -1;
};

/// Progress of long work. Return false to cancel; the work then throws Cancelled
/// (base/error.h) at its next check. Never called concurrently, but not always from the
/// thread that started the work (a bake reports from whichever thread merged the tile).
using ProgressFn = std::function<bool(const Progress&)>;

/// Seconds since `start`, for stage timing.
inline double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace cpvs
