// The streaming merge: tile results merged, in the order they are acknowledged, by one
// thread per coordinator, into each job's StreamingMerger; the job's artifact written when
// its last tile is in.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <stdexcept>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "coordinator/artifact_store.h"
#include "coordinator/change_feed.h"
#include "coordinator/farm_metrics.h"
#include "cpvs/dag/assemble_roots.h"
#include "cpvs/dag/merge.h"
#include "cpvs/dag/streaming_merger.h"
#include "cpvs/dagmh/dag_mh.h"
#include "cpvs/scene/scene.h"
#include "store/farm_store.h"

namespace cpvs::server {

class MergeScheduler {
 public:
  /// `failJob` ends a job whose merge failed (a damaged tile file, a full disk).
  using FailJob = std::function<void(const std::string& jobId, const std::string& why)>;
  /// The imported scene of an upload (SceneStore::load): a sun artifact of a scene with
  /// translucent meshes carries their TOP tree, built here once its DAG is merged.
  using LoadScene = std::function<Scene(const std::string& sceneHash)>;
  MergeScheduler(FarmStore& store, ArtifactStore& artifacts, ChangeFeed& feed, FarmMetrics& metrics, FailJob failJob,
                 LoadScene loadScene);
  ~MergeScheduler() { stop(); }

  /// Starts the merge thread.
  void start();
  /// Stops it; queued work stays in the store (acknowledged tiles) for the next start.
  void stop();

  /// Merges an acknowledged tile result.
  void mergeTile(const std::string& jobId, uint64_t tile);
  /// Removes an ended job's tile results, after any merge of them queued before, so that
  /// a merge never finds a file gone under it.
  void removeTiles(const std::string& jobId);
  /// Tiles and artifacts waiting for the merge thread (queued or to be tried again).
  size_t backlog();

 private:
  struct Item {
    enum class Kind { MergeTile, RemoveTiles, WriteArtifact } kind;
    std::string jobId;
    uint64_t tile = 0;
  };
  /// One grid of a job (the sun's only one, or a light bundle's): its tiles merged as
  /// they come, then its levels above the tile roots assembled once all are in.
  struct GridMerge {
    std::unique_ptr<StreamingMerger> merger;
    uint64_t merged = 0;
    std::optional<Dag> dag;
  };
  struct JobMerge {
    std::vector<GridMerge> grids;
    std::unique_ptr<DagMhBuilder> dagMh;  // a DAG-MH job's: its tiles' parts merged as they come
    std::optional<DagMh> dagMhDone;       // and built once all are in
    uint64_t merged = 0;
    uint64_t peak = 0;
    // The finished artifact, kept until it is written and the job marked done: a full
    // disk delays it, and the write is tried again with nothing merged twice (R9).
    std::vector<uint8_t> file;
    uint64_t dagBytes = 0;
  };

  /// A tile result that cannot be read back: baked again rather than failing the job.
  struct TileUnreadable : std::runtime_error {
    using std::runtime_error::runtime_error;
  };

  void push(Item item);
  /// Queues `item` again after a pause (the store or the disk could not take it now).
  void retryLater(Item item);
  void failJob(const std::string& jobId, const std::string& why);
  void loop();
  void mergeOne(const std::string& jobId, uint64_t tile);
  /// A DAG-MH job's tile (mergeOne's): its parts into the job's builder.
  void mergeDagMhTile(const JobRecord& j, JobMerge& m, uint64_t tile);
  /// Writes the artifact and marks the job done; false when that must be tried again.
  bool finishJob(const JobRecord& job, JobMerge& m);

  FarmStore& store_;
  ArtifactStore& artifacts_;
  ChangeFeed& feed_;
  FarmMetrics& metrics_;
  FailJob failJob_;
  LoadScene loadScene_;

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Item> queue_;
  std::vector<std::pair<std::chrono::steady_clock::time_point, Item>> later_;
  bool stopping_ = false;
  std::map<std::string, JobMerge> merges_;  // the merge thread's only
  std::thread thread_;
};

}  // namespace cpvs::server
