// A farm worker: leases tiles from the coordinator, bakes their sub-DAGs with the core,
// and returns them. Scenes and their Embree BVHs are cached by content hash, so a BVH is
// built once per scene and grid origin, not once per tile.
#pragma once

#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/tile_cache.h"
#include "cpvs/scene/isolated_import.h"
#include "cpvs/scene/source.h"
#include "cpvs/v1/farm.grpc.pb.h"
#include "cpvs/net/channel.h"
#include "worker_metrics.h"

namespace cpvs::worker {

namespace pb = ::cpvs::v1;

struct WorkerConfig {
  net::Connection server;
  int slots = 1;           // tiles baked at once
  std::string cacheDir;    // fetched scene files
  std::string workerId;    // for the coordinator's logs
  int maxTiles = 0;        // stop after this many tiles (0 = never; for tests)
  int threads = 0;         // threads per bake, Embree's and the DAG construction's (0 = all cores)
  /// Tiles' sub-DAGs kept in cacheDir/tiles under the content that decides them
  /// (tile_key.h): a tile leased again, by this job or another, is sent from there
  /// instead of baked. At most this many MiB, least recently used out; 0: none kept.
  uint64_t tileCacheMb = 4096;
  /// How fetched scene files are imported: in cpvs-import's sandbox (cpvs-worker's
  /// default), or in this process when it names no helper (tests that embed a worker).
  ImportLimits import;
};

/// The file in the cache folder a worker touches (at most every 5 s) whenever the
/// coordinator answers it, leasing or renewing: `cpvs-worker --check` reads its age.
std::string alivePath(const std::string& cacheDir);

class TileWorker {
 public:
  explicit TileWorker(WorkerConfig config);

  /// Runs the pull loop on `slots` threads until stop() (or maxTiles); reconnects with
  /// backoff when the coordinator is unreachable.
  void run();
  /// Graceful stop: no new leases; tiles in progress finish and are returned.
  void stop() {
    stopping_ = true;
    metrics_.draining();
  }
  /// Hard stop: tiles in progress are abandoned and their leases released.
  void abandon() {
    stopping_ = true;
    abandoning_ = true;
  }
  uint64_t tilesDone() const { return tilesDone_; }
  /// Of the tiles done, those sent from the tile cache without baking.
  uint64_t tilesReused() const { return tilesReused_; }
  /// Leases granted to this worker (a tile's completion is counted once its reply is
  /// read, which may be after the job it finished is done).
  uint64_t tilesLeased() const { return tilesStarted_; }
  /// Gives the tiles in progress back now (interrupted: it costs them no attempt), while
  /// their bakes still run: a stop that cannot wait for them (a drain's deadline). Returns
  /// how many were given back; the process is expected to leave next.
  size_t releaseInFlight();
  WorkerMetrics& metrics() { return metrics_; }

 private:
  struct CachedScene {
    Scene scene;
    std::map<std::string, std::shared_ptr<BakeScene>> prepared;  // by grid and renderer
    std::mutex mutex;
  };

  void slotLoop(int slot);
  /// The coordinator answered: touches alivePath (at most every 5 s).
  void noteContact();
  /// Bakes and returns one leased tile; false when the coordinator is unreachable.
  void bakeLeased(const pb::TileLease& lease);
  /// The scene prepared for a lease's grid (a sun's or a light bundle's perspective one)
  /// and renderer, without the light's fixture (`exclude`, Light::exclude), loaded and
  /// built once; InputError for a grid or a fixture the core refuses.
  std::shared_ptr<BakeScene> bakeScene(const std::string& sceneHash, const v1::GridSpec& grid, Renderer renderer,
                                       const v1::Receivers& receivers, const std::vector<std::string>& exclude);
  /// The cached file of a scene, fetched when missing; WorkerFault for trouble of the
  /// worker's own or a damaged scene.
  std::string fetchScene(const std::string& sceneHash);
  /// Fetches a scene and imports it under config_.import.
  Scene importScene(const std::string& sceneHash);
  std::string fetchSceneOnce(const std::string& sceneHash);
  /// sendResult, again with backoff while the coordinator is unreachable.
  void deliverResult(const pb::TileLease& lease, const std::vector<uint8_t>& encoded,
                     const std::map<std::string, double>& stages, bool reused);
  void sendResult(const pb::TileLease& lease, const std::vector<uint8_t>& encoded,
                  const std::map<std::string, double>& stages, bool reused);
  void release(const pb::TileLease& lease, const std::string& reason, pb::FailKind kind = pb::FAIL_TILE);

  WorkerConfig config_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<pb::Workers::Stub> stub_;
  std::atomic<bool> stopping_{false}, abandoning_{false};
  std::atomic<uint64_t> tilesDone_{0}, tilesStarted_{0}, tilesReused_{0};
  std::unique_ptr<TileCache> tileCache_;  // null when tileCacheMb is 0
  std::atomic<int64_t> lastContactMs_{-5000};
  std::mutex cacheMutex_, fetchMutex_;
  std::map<std::string, std::shared_ptr<CachedScene>> cache_;
  std::mutex inFlightMutex_;
  std::map<std::string, pb::TileLease> inFlight_;  // by lease id
  WorkerMetrics metrics_;
};

}  // namespace cpvs::worker
