// The coordinator's logic, free of gRPC: scenes, jobs, tile leases, the streaming merge
// of sub-DAGs as they arrive, and the artifacts. The services in farm_service.cpp are a
// thin edge over it; errors are FarmError values.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "cpvs/scene/import.h"
#include "cpvs/dag/merge.h"
#include "cpvs/v1/farm.pb.h"
#include "cpvs/net/status.h"
#include "farm_store.h"

namespace cpvs::server {

namespace pb = ::cpvs::v1;
using net::ErrorKind;
using net::FarmError;

struct CoordinatorConfig {
  std::string dataDir;                         // SQLite database, scenes, tile results, artifacts
  double leaseSeconds = 30;                    // a worker renews well before this
  int maxAttempts = 3;                         // a tile that fails or expires this often fails its job
  int maxLog2Resolution = 18;                  // 256K
  int minLog2Resolution = 6;                   // 64
  uint64_t maxUploadBytes = uint64_t(4) << 30; // per scene
  size_t maxActiveJobs = 64;
};

class Coordinator {
 public:
  /// Opens the data folder and resumes every unfinished job from what is on disk: tiles
  /// acknowledged before a restart are merged again from their files, never rebuilt.
  explicit Coordinator(CoordinatorConfig config);
  ~Coordinator();

  // --- scenes ---
  pb::UploadStatus uploadStatus(const std::string& sceneHash);
  /// Starts or resumes an upload; `offset` must equal the bytes already received.
  void beginUpload(const pb::UploadSceneChunk& first);
  /// Appends data at `offset` (the bytes received so far).
  void appendUpload(const std::string& sceneHash, uint64_t offset, const std::string& data);
  /// Completes the upload when every byte is in: checks the hash, imports the scene.
  pb::UploadSceneReply endUpload(const std::string& sceneHash);
  /// The stored file of a complete scene (for workers).
  std::string scenePath(const std::string& sceneHash, std::string* fileName = nullptr);

  // --- jobs ---
  pb::JobStatus submit(const pb::SubmitBakeRequest& request);
  pb::JobStatus status(const std::string& jobId);
  std::vector<pb::JobStatus> list(bool includeFinished);
  pb::JobStatus cancel(const std::string& jobId);
  /// The artifact of a finished job and its checksum (hex).
  std::string artifactPath(const std::string& jobId, std::string* checksum);

  /// A counter bumped on every job change; waitForChange blocks until it passes `seen`
  /// or the timeout ends, and returns the current value.
  uint64_t waitForChange(uint64_t seen, int timeoutMs);

  // --- workers ---
  pb::TileLease lease(const std::string& workerId);
  pb::RenewReply renew(const std::string& leaseId);
  /// A tile's sub-DAG, validated; false when another result for the tile was taken.
  bool completeTile(const std::string& leaseId, const std::string& encoded, const std::map<std::string, double>& stages);
  void failTile(const std::string& leaseId, const std::string& reason);

  /// Stops the background threads (also done by the destructor).
  void stop();

 private:
  struct MergeState {
    std::unique_ptr<StreamingMerger> merger;
    uint64_t merged = 0;
    uint64_t peak = 0;
  };

  pb::JobStatus toStatus(const JobRecord& j) const;
  std::string tilePath(const std::string& jobId, uint64_t tile) const;
  std::string artifactFile(const std::string& jobId) const;
  /// Removes the folder of a job's tile results (done, cancelled or failed jobs).
  void removeTileResults(const std::string& jobId) const;
  void notify();
  void failJob(const std::string& jobId, const std::string& error);
  /// Ends an unfinished job as cancelled or failed; false when it had already ended.
  bool endJob(const std::string& jobId, JobState state, const std::string& why);
  void reaperLoop();
  void mergeLoop();
  void mergeOne(const std::string& jobId, uint64_t tile);
  void finishJob(const std::string& jobId, MergeState& m);

  CoordinatorConfig config_;
  FarmStore store_;
  std::mutex uploadMutex_;
  std::mutex submitMutex_;  // a request id's check and its job's creation, see submit
  std::mutex resultMutex_;  // one tile result decided and written at a time, see completeTile

  std::mutex changeMutex_;
  std::condition_variable changed_;
  uint64_t version_ = 0;

  std::mutex mergeMutex_;
  std::condition_variable mergeWake_;
  /// (job, tile) to merge, or (job, kRemoveTiles): the job ended, remove its tile results.
  std::deque<std::pair<std::string, uint64_t>> mergeQueue_;
  static constexpr uint64_t kRemoveTiles = ~uint64_t{0};
  std::map<std::string, MergeState> merges_;  // touched by the merge thread only

  bool stopping_ = false;
  std::thread reaper_, mergeThread_;
};

}  // namespace cpvs::server
