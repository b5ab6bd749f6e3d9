#include "coordinator/housekeeper.h"

#include <algorithm>

#include <spdlog/spdlog.h>

#include "coordinator/clock.h"

namespace cpvs::server {

Housekeeper::Housekeeper(FarmStore& store, ArtifactStore& artifacts, SceneStore& scenes, RetentionRules rules)
    : store_(store), artifacts_(artifacts), scenes_(scenes), rules_(rules) {}

void Housekeeper::start() {
  try {
    // The store forgets a job or a scene before its files go: files it does not know are
    // what a crash between the two left behind.
    for (const std::string& jobId : artifacts_.jobsWithArtifacts())
      if (!store_.job(jobId)) {
        artifacts_.removeArtifact(jobId);
        spdlog::info("removed the artifact of job {}, which the store no longer holds", jobId);
      }
    if (const size_t files = scenes_.removeOrphanFiles())
      spdlog::info("removed {} scene file(s) of scenes the store no longer holds", files);
    runOnce();
  } catch (const std::exception& e) {
    spdlog::error("housekeeping at start failed: {}", e.what());  // the coordinator serves anyway
  }
  stopping_ = false;
  thread_ = std::thread([this] { loop(); });
}

void Housekeeper::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void Housekeeper::runOnce() {
  try {
    if (rules_.uploadExpirySeconds > 0)
      scenes_.expireIdleUploads(std::chrono::seconds(int64_t(std::max(1.0, rules_.uploadExpirySeconds))));
    if (rules_.keepFinishedSeconds > 0) {
      const int64_t before = nowMs() - int64_t(rules_.keepFinishedSeconds * 1000);
      // In batches: one transaction never holds the store for long.
      size_t pruned = 0;
      for (;;) {
        const std::vector<std::string> ids = store_.pruneFinishedJobs(before, 256);
        for (const std::string& id : ids) {
          artifacts_.removeArtifact(id);
          artifacts_.removeTiles(id);
        }
        pruned += ids.size();
        if (ids.size() < 256) break;
      }
      if (pruned) spdlog::info("pruned {} job(s) that ended more than {} s ago", pruned, rules_.keepFinishedSeconds);
      if (const size_t scenes = scenes_.pruneUnused(before))
        spdlog::info("pruned {} scene(s) no job used for {} s", scenes, rules_.keepFinishedSeconds);
    }
  } catch (const StoreUnavailable& e) {
    spdlog::warn("housekeeping put off: {}", e.what());  // the next round tries again
  }
}

void Housekeeper::loop() {
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    wake_.wait_for(lock, std::chrono::milliseconds(int64_t(rules_.intervalSeconds * 1000)), [&] { return stopping_; });
    if (stopping_) break;
    lock.unlock();
    try {
      runOnce();
    } catch (const std::exception& e) {
      // Housekeeping never takes the coordinator down (R9): the next round tries again.
      spdlog::error("housekeeping failed: {}", e.what());
    }
    lock.lock();
  }
}

}  // namespace cpvs::server
