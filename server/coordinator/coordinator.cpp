#include "coordinator/coordinator.h"

#include <spdlog/spdlog.h>

#include <filesystem>

#include "cpvs/net/convert.h"
#include "coordinator/stored_spec.h"

namespace cpvs::server {

namespace fs = std::filesystem;

namespace {

std::string databasePath(const std::string& dataDir) { return (fs::path(dataDir) / "farm.sqlite").string(); }

}  // namespace

Coordinator::Coordinator(CoordinatorConfig config)
    : config_(std::move(config)),
      lock_(config_.dataDir),
      store_(databasePath(config_.dataDir), legacySpecRewrite()),
      artifacts_(config_.dataDir),
      scenes_(store_, config_.dataDir, config_.maxUploadBytes, config_.import, config_.maxConcurrentImports,
              config_.maxPendingUploads, config_.clientUploads),
      merges_(store_, artifacts_, feed_, metrics_, [this](const std::string& jobId, const std::string& why) {
        jobs_.failJob(jobId, why);
      }, [this](const std::string& sceneHash) { return scenes_.load(sceneHash); }),
      jobs_(store_, scenes_, artifacts_, merges_, feed_,
            JobLimits{config_.minLog2Resolution, config_.maxLog2Resolution, config_.maxActiveJobs,
                      config_.maxActiveJobsPerClient, config_.maxTilesPerJob}),
      leases_(store_, scenes_, artifacts_, merges_, jobs_, feed_, metrics_,
              LeaseRules{config_.leaseSeconds, config_.maxAttempts, config_.maxTileSeconds, config_.quarantineSeconds}),
      tracks_(store_, jobs_, feed_),
      housekeeper_(store_, artifacts_, scenes_, config_.retention) {
  // Resume: every acknowledged tile of an unfinished job goes back into its merge.
  size_t jobs = 0, tiles = 0;
  for (const auto& j : store_.jobs(false)) {
    for (uint64_t t : store_.doneTiles(j.id)) {
      merges_.mergeTile(j.id, t);
      ++tiles;
    }
    ++jobs;
  }
  if (jobs) spdlog::info("resuming {} unfinished job(s), {} acknowledged tile(s) to merge", jobs, tiles);
  // Tile results of jobs that ended (cancelled or failed) while the coordinator was down
  // before the merge thread removed them.
  for (const std::string& jobId : artifacts_.jobsWithTiles()) {
    auto j = store_.job(jobId);
    if (!j || isFinal(j->state)) artifacts_.removeTiles(jobId);
  }
  // Temporaries of atomic writes a crash left behind (R25).
  std::error_code ec;
  for (const auto& entry : fs::recursive_directory_iterator(config_.dataDir, ec))
    if (entry.is_regular_file(ec) && entry.path().filename().string().find(".tmp.") != std::string::npos)
      fs::remove(entry.path(), ec);
  merges_.start();
  leases_.start();
  tracks_.start();  // active tracks carry on from what the store holds
  housekeeper_.start();
}

Coordinator::~Coordinator() { stop(); }

void Coordinator::refreshMetrics() {
  FarmReadings r;
  r.storeHealthy = healthy();
  if (r.storeHealthy) {
    // A store that does not answer keeps the last counts rather than holding the scrape.
    const FarmStore::Census c = store_.census();
    for (const auto& [state, count] : c.jobs) r.jobsByState[net::jobStateName(net::JobState(int(state)))] = count;
    r.tilesQueued = c.tilesQueued;
    r.tilesLeased = c.tilesLeased;
    r.artifactBytes = c.artifactBytes;
  }
  r.mergeBacklog = merges_.backlog();
  std::error_code ec;
  for (const char* suffix : {"", "-wal"}) {
    const auto size = fs::file_size(databasePath(config_.dataDir) + suffix, ec);
    if (!ec) r.storeBytes += size;
  }
  r.tracksActive = tracks_.activeTracks();
  r.keyframeLag = tracks_.keyframeLag();
  metrics_.set(r);
}

void Coordinator::stop() {
  if (stopped_) return;
  stopped_ = true;
  housekeeper_.stop();
  tracks_.stop();
  leases_.stop();
  merges_.stop();
  feed_.wakeAll();
}

}  // namespace cpvs::server
