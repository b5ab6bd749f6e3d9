// Tiles out to workers: leased in priority and fairness order, renewed while baking,
// expired by the reaper, failed and retried a bounded number of times, completed with a
// validated sub-DAG (the first result of a tile wins).
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <map>
#include <mutex>
#include <string>
#include <thread>

#include "coordinator/artifact_store.h"
#include "coordinator/change_feed.h"
#include "coordinator/farm_metrics.h"
#include "coordinator/job_service.h"
#include "coordinator/merge_scheduler.h"
#include "coordinator/scene_store.h"
#include "cpvs/v1/farm.pb.h"
#include "store/farm_store.h"

namespace cpvs::server {

struct LeaseRules {
  double leaseSeconds = 30;  // a worker renews well before this
  int maxAttempts = 3;       // a tile that fails or expires this often fails its job
  double maxTileSeconds = 3600;  // no renewal beyond this after the lease was granted (a hung bake)
  double quarantineSeconds = 30;  // a failing worker's first pause without tiles (doubling, to 10 min)
};

/// A worker that fails this many tiles in a row (or reports its own trouble once) gets no
/// tile for a while: one broken worker cannot burn every tile's attempts.
constexpr int kQuarantineAfterFailures = 3;
constexpr double kMaxQuarantineSeconds = 600;

class LeaseService {
 public:
  LeaseService(FarmStore& store, SceneStore& scenes, ArtifactStore& artifacts, MergeScheduler& merges, JobService& jobs,
               ChangeFeed& feed, FarmMetrics& metrics, LeaseRules rules);
  ~LeaseService() { stop(); }

  /// Starts and stops the reaper thread, which returns expired leases to the queue.
  void start();
  void stop();

  pb::TileLease lease(const std::string& workerId);
  pb::RenewReply renew(const std::string& leaseId);
  /// FarmError(NotFound) unless the lease exists: checked on a result's first chunk,
  /// before the rest of the stream is read.
  void checkResultLease(const std::string& leaseId);
  /// A tile's sub-DAG, validated; false when another result for the tile was taken.
  /// `reused`: the worker sent the tile from its tile cache (counted, kept out of the ETA).
  bool completeTile(const std::string& leaseId, const std::string& encoded, const std::map<std::string, double>& stages,
                    bool reused = false);
  /// A tile given back. Only FAIL_TILE counts against the tile's attempts; FAIL_WORKER
  /// and FAIL_SCENE_DAMAGED quarantine the worker (the latter after the coordinator
  /// checked its stored copy of the scene); FAIL_INTERRUPTED costs nothing.
  void failTile(const std::string& leaseId, const std::string& reason, pb::FailKind kind = pb::FAIL_TILE);
  /// Seconds since the reaper last finished a round (expired what was due, recorded
  /// renewals): leases move while this stays near a quarter second.
  double secondsSinceReaperRound() const;
  /// Whether a worker is kept from tiles now (and for how many more milliseconds).
  int64_t quarantinedForMs(const std::string& workerId);

 private:
  void reaperLoop();
  bool takeResult(const std::string& leaseId, const std::string& encoded, const std::map<std::string, double>& stages,
                  bool reused);
  /// Notes a worker's failure (under workersMutex_) and quarantines it when due.
  void noteWorkerFailure(const std::string& workerId, bool quarantineNow);

  FarmStore& store_;
  SceneStore& scenes_;
  ArtifactStore& artifacts_;
  MergeScheduler& merges_;
  JobService& jobs_;
  ChangeFeed& feed_;
  FarmMetrics& metrics_;
  LeaseRules rules_;

  std::mutex mutex_;
  std::condition_variable wake_;  // the reaper's own: merges do not wake it
  bool stopping_ = false;
  std::thread reaper_;
  std::atomic<int64_t> lastRoundSteadyMs_{0};

  // Failing workers, by id: in memory (a restart forgives them). Bounded: a worker's entry
  // goes when it completes a tile, and the whole map is cut when it grows past 10,000.
  struct WorkerRecord {
    int failuresInARow = 0;
    int quarantines = 0;
    std::chrono::steady_clock::time_point until{};
  };
  // Renewals the store could not record when they came (a full disk): recorded by the
  // reaper before it expires anything.
  std::mutex pendingMutex_;
  std::map<std::string, int64_t> pendingRenewals_;

  std::mutex workersMutex_;
  std::map<std::string, WorkerRecord> workers_;
};

}  // namespace cpvs::server
