// Tiles out to workers: leased in priority and fairness order, renewed while baking,
// expired by the reaper, failed and retried a bounded number of times, completed with a
// validated sub-DAG (the first result of a tile wins).
#pragma once

#include <condition_variable>
#include <map>
#include <mutex>
#include <string>
#include <thread>

#include "coordinator/artifact_store.h"
#include "coordinator/change_feed.h"
#include "coordinator/job_service.h"
#include "coordinator/merge_scheduler.h"
#include "cpvs/v1/farm.pb.h"
#include "store/farm_store.h"

namespace cpvs::server {

struct LeaseRules {
  double leaseSeconds = 30;  // a worker renews well before this
  int maxAttempts = 3;       // a tile that fails or expires this often fails its job
  double maxTileSeconds = 3600;  // no renewal beyond this after the lease was granted (a hung bake)
};

class LeaseService {
 public:
  LeaseService(FarmStore& store, ArtifactStore& artifacts, MergeScheduler& merges, JobService& jobs, ChangeFeed& feed,
               LeaseRules rules);
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
  bool completeTile(const std::string& leaseId, const std::string& encoded, const std::map<std::string, double>& stages);
  void failTile(const std::string& leaseId, const std::string& reason);

 private:
  void reaperLoop();

  FarmStore& store_;
  ArtifactStore& artifacts_;
  MergeScheduler& merges_;
  JobService& jobs_;
  ChangeFeed& feed_;
  LeaseRules rules_;

  std::mutex mutex_;
  std::condition_variable wake_;  // the reaper's own: merges do not wake it
  bool stopping_ = false;
  std::thread reaper_;
};

}  // namespace cpvs::server
