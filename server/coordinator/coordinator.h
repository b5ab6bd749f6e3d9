// The coordinator's logic, free of gRPC, as seven concerns wired together: the scene store
// (uploads), the job service (lifecycle), the lease service (tiles out to workers, the
// reaper), the merge scheduler (the streaming merge), the artifact store (bytes on disk),
// the track service (sun keyframes ahead, published as versions) and the housekeeper
// (retention of finished jobs, expiry of abandoned uploads), over the durable
// FarmStore. The services in rpc/ are a thin edge over it; errors
// are FarmError values.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "coordinator/artifact_store.h"
#include "coordinator/change_feed.h"
#include "coordinator/data_folder_lock.h"
#include "coordinator/farm_metrics.h"
#include "coordinator/housekeeper.h"
#include "coordinator/job_service.h"
#include "coordinator/lease_service.h"
#include "coordinator/merge_scheduler.h"
#include "coordinator/scene_store.h"
#include "coordinator/track_service.h"
#include "cpvs/net/error_kind.h"
#include "cpvs/v1/farm.pb.h"
#include "store/farm_store.h"

namespace cpvs::server {

namespace pb = ::cpvs::v1;
using net::ErrorKind;
using net::FarmError;

struct CoordinatorConfig {
  std::string dataDir;                          // SQLite database, scenes, tile results, artifacts
  double leaseSeconds = 30;                     // a worker renews well before this
  int maxAttempts = 3;                          // a tile that fails or expires this often fails its job
  double maxTileSeconds = 3600;                 // the longest one tile may be renewed for
  double quarantineSeconds = 30;                // a failing worker's first pause (see LeaseRules)
  int maxLog2Resolution = 18;                   // 256K
  int minLog2Resolution = 6;                    // 64
  uint64_t maxUploadBytes = uint64_t(4) << 30;  // per scene
  size_t maxActiveJobs = 64;
  size_t maxActiveJobsPerClient = 32;           // see JobLimits
  uint64_t maxTilesPerJob = 65536;              // see JobLimits
  ImportLimits import;                          // how uploads are imported (isolated when it names a helper)
  int maxConcurrentImports = 2;
  int maxWatches = 256;                         // WatchJob and Subscribe streams open at once
  size_t maxPendingUploads = 64;                // uploads started and not complete
  ClientUploadQuota clientUploads;              // bytes of one client's uploads and scenes
  RetentionRules retention;                     // finished jobs and abandoned uploads forgotten
};

class Coordinator {
 public:
  /// Opens the data folder and resumes every unfinished job from what is on disk: tiles
  /// acknowledged before a restart are merged again from their files, never rebuilt.
  explicit Coordinator(CoordinatorConfig config);
  ~Coordinator();

  const CoordinatorConfig& config() const { return config_; }
  /// Whether the coordinator can take work now: its store answers within half a second.
  bool healthy() { return store_.responsive(500); }
  /// Whether leases move: the reaper finished a round within the last 10 seconds (it runs
  /// four a second; a wedged store or a stuck thread stops it).
  bool leasesMoving() const { return leases_.secondsSinceReaperRound() < 10; }
  SceneStore& scenes() { return scenes_; }
  JobService& jobs() { return jobs_; }
  LeaseService& leases() { return leases_; }
  TrackService& tracks() { return tracks_; }
  FarmMetrics& metrics() { return metrics_; }
  /// Takes the readings a scrape reports (jobs and tiles by state, backlogs, the store's
  /// size and health); the endpoint calls it before each scrape.
  void refreshMetrics();

  /// A counter bumped on every job change; waitForChange blocks until it passes `seen`
  /// or the timeout ends, and returns the current value.
  uint64_t waitForChange(uint64_t seen, int timeoutMs) { return feed_.waitForChange(seen, timeoutMs); }

  /// Stops the background threads (also done by the destructor).
  void stop();

 private:
  CoordinatorConfig config_;
  DataFolderLock lock_;  // first: nothing is opened in a folder another server holds
  FarmStore store_;
  ChangeFeed feed_;
  FarmMetrics metrics_;
  ArtifactStore artifacts_;
  SceneStore scenes_;
  MergeScheduler merges_;
  JobService jobs_;
  LeaseService leases_;
  TrackService tracks_;
  Housekeeper housekeeper_;
  bool stopped_ = false;
};

}  // namespace cpvs::server
