// A counter of changes to jobs, and waiting for the next one: what WatchJob follows.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <mutex>

namespace cpvs::server {

class ChangeFeed {
 public:
  /// Something about a job changed.
  void notify() {
    {
      std::lock_guard lock(mutex_);
      ++version_;
    }
    changed_.notify_all();
  }
  /// Blocks until the counter passes `seen`, the timeout ends or wakeAll(); returns it.
  uint64_t waitForChange(uint64_t seen, int timeoutMs) {
    std::unique_lock lock(mutex_);
    changed_.wait_for(lock, std::chrono::milliseconds(timeoutMs), [&] { return version_ != seen; });
    return version_;
  }
  /// Wakes every waiter (at shutdown).
  void wakeAll() { changed_.notify_all(); }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  uint64_t version_ = 0;
};

}  // namespace cpvs::server
