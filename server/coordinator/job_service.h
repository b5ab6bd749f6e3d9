// The lifecycle of jobs: submitted (idempotent by request id, within quotas), followed,
// cancelled or failed (the first end stands), done with an artifact.
#pragma once

#include <chrono>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "coordinator/access.h"
#include "coordinator/artifact_store.h"
#include "coordinator/change_feed.h"
#include "coordinator/merge_scheduler.h"
#include "coordinator/scene_store.h"
#include "cpvs/net/farm_model.h"
#include "cpvs/v1/farm.pb.h"
#include "store/farm_store.h"

namespace cpvs::server {

struct JobLimits {
  int minLog2Resolution = 6;   // 64
  int maxLog2Resolution = 18;  // 256K
  size_t maxActiveJobs = 64;
  size_t maxActiveJobsPerClient = 32;  // of them, one client's (an owner's; admin not counted)
  /// Most tiles one job may have: 65536 is 256K³ in tiles of 1024 texels. Bounds the rows
  /// a submit creates and the work one client can ask for in one request.
  uint64_t maxTilesPerJob = 65536;
};

/// A ListJobs reply stays well inside gRPC's 4 MiB message limit and a client's default.
constexpr size_t kListReplyBytes = 512 * 1024;

class JobService {
 public:
  JobService(FarmStore& store, SceneStore& scenes, ArtifactStore& artifacts, MergeScheduler& merges, ChangeFeed& feed,
             JobLimits limits);

  /// Jobs are the submitting client's (`access`): another client's job is PermissionDenied
  /// to status, cancel and artifactPath, and missing from its listing (R28).
  /// A job for `spec`, or the job `requestId` already names when it names the same spec
  /// (AlreadyExists when another).
  pb::JobStatus submit(const std::string& requestId, const net::BakeSpec& spec, const Access& access = Access::all());
  pb::JobStatus status(const std::string& jobId, const Access& access = Access::all());
  /// One page of the listing, oldest first (R16): at most `pageSize` jobs (0: 100, at most
  /// 1000) and fewer when the reply would pass kListReplyBytes; the next page starts after
  /// the position in `pageToken` (empty: the start). nextPageToken is empty on the last page.
  struct Page {
    std::vector<pb::JobStatus> jobs;
    std::string nextPageToken;
  };
  Page list(bool includeFinished, uint32_t pageSize = 0, const std::string& pageToken = "",
            const Access& access = Access::all());
  pb::JobStatus cancel(const std::string& jobId, const Access& access = Access::all());
  /// The artifact of a finished job and its checksum (hex).
  std::string artifactPath(const std::string& jobId, std::string* checksum, const Access& access = Access::all());

  /// Ends an unfinished job as failed (logged); a job already ended keeps its end.
  void failJob(const std::string& jobId, const std::string& error);
  /// Held while a tile result is decided and written, and while a job ends: no result of
  /// a job is written after its tiles are cancelled.
  std::mutex& resultMutex() { return resultMutex_; }

 private:
  pb::JobStatus toStatus(const JobRecord& j) const;
  /// The job's tile costs (FarmStore::tileCosts), read again at most every 5 s: each is
  /// a pass over its tiles under the store's lock, and every watch asks once a second.
  TileCosts costsOf(const std::string& jobId) const;
  /// Ends an unfinished job as cancelled or failed; false when it had already ended.
  bool endJob(const std::string& jobId, JobState state, const std::string& why);
  /// The job a request id already names: the same spec is a retry, another is refused.
  std::optional<pb::JobStatus> knownRequest(const pb::SubmitBakeRequest& request, const Access& access);
  /// The job, when `access` may see it: NotFound, PermissionDenied otherwise.
  JobRecord visibleJob(const std::string& jobId, const Access& access);
  void checkRoom(const Access& access);
  /// A light bundle's submit (lights or scene_lights): planned at once, a tile per
  /// (grid, tile) of its grids.
  pb::JobStatus submitBundle(const pb::SubmitBakeRequest& request, const Access& access);
  /// Gives the job its identity from the request (id, owner, scene, spec, priority, time)
  /// and creates it with its tiles in `states` (done ones queued for merging) and their
  /// `work` (none known when empty: a bundle's ETA counts tiles); the job a retry names
  /// instead, when one does.
  std::optional<pb::JobStatus> createJob(const pb::SubmitBakeRequest& request, const Access& access,
                                         const Scene& scene, JobRecord& j, const std::vector<TileState>& states,
                                         const std::vector<uint32_t>& work = {});
  void checkTileCount(uint64_t tiles, const std::string& what) const;

  FarmStore& store_;
  SceneStore& scenes_;
  ArtifactStore& artifacts_;
  MergeScheduler& merges_;
  ChangeFeed& feed_;
  JobLimits limits_;
  std::mutex submitMutex_;  // a request id's check and its job's creation, see submit
  mutable std::mutex costsMutex_;
  mutable std::map<std::string, std::pair<std::chrono::steady_clock::time_point, TileCosts>> costs_;
  std::mutex resultMutex_;
};

}  // namespace cpvs::server
