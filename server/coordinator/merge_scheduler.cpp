#include "coordinator/merge_scheduler.h"

#include <spdlog/spdlog.h>

#include "coordinator/failpoint.h"
#include "cpvs/bake/bake.h"
#include "cpvs/bake/tile_plan.h"
#include "cpvs/base/error.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/progress.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/io/sub_dag_file.h"
#include "coordinator/clock.h"

namespace cpvs::server {

MergeScheduler::MergeScheduler(FarmStore& store, ArtifactStore& artifacts, ChangeFeed& feed, FailJob failJob)
    : store_(store), artifacts_(artifacts), feed_(feed), failJob_(std::move(failJob)) {}

void MergeScheduler::start() { thread_ = std::thread([this] { loop(); }); }

void MergeScheduler::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void MergeScheduler::push(Item item) {
  {
    std::lock_guard lock(mutex_);
    queue_.push_back(std::move(item));
  }
  wake_.notify_all();
}

void MergeScheduler::mergeTile(const std::string& jobId, uint64_t tile) { push({Item::Kind::MergeTile, jobId, tile}); }

void MergeScheduler::removeTiles(const std::string& jobId) { push({Item::Kind::RemoveTiles, jobId, 0}); }

void MergeScheduler::failJob(const std::string& jobId, const std::string& why) {
  // The merge thread outlives any one failure (R9): a store that cannot record this one
  // now is logged, and the job's tiles stay for the next start.
  try {
    failJob_(jobId, why);
  } catch (const std::exception& e) {
    spdlog::error("job {}: {} (and it could not be recorded: {})", jobId, why, e.what());
  }
}

void MergeScheduler::loop() {
  for (;;) {
    Item item;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (stopping_) return;
      item = std::move(queue_.front());
      queue_.pop_front();
    }
    if (item.kind == Item::Kind::RemoveTiles) {
      merges_.erase(item.jobId);
      artifacts_.removeTiles(item.jobId);
      continue;
    }
    try {
      mergeOne(item.jobId, item.tile);
    } catch (const TileUnreadable& e) {
      // An acknowledged tile whose file is gone or damaged (a crash, a bad disk) is baked
      // again, that tile only (R4); the tiles merged so far stay merged.
      spdlog::warn("{}: baking it again", e.what());
      try {
        store_.requeueDoneTile(item.jobId, item.tile, e.what());
        feed_.notify();
      } catch (const std::exception& again) {
        failJob(item.jobId, std::string("merge failed: ") + e.what() + "; " + again.what());
      }
    } catch (const std::exception& e) {
      merges_.erase(item.jobId);
      failJob(item.jobId, std::string("merge failed: ") + e.what());
    }
  }
}

void MergeScheduler::mergeOne(const std::string& jobId, uint64_t tile) {
  auto j = store_.job(jobId);
  if (!j || isFinal(j->state)) {
    merges_.erase(jobId);
    return;
  }
  JobMerge& m = merges_[jobId];
  if (!m.merger) m.merger = std::make_unique<StreamingMerger>(j->options.compress);
  const auto start = std::chrono::steady_clock::now();
  Dag dag;
  if (store_.tileState(jobId, tile) == TileState::Untouched) {
    const TileCoord at = TilePlan(j->grid.log2Resolution, j->options.log2TileSize).tile(tile);
    dag = bakeUntouchedTile(j->grid, at.x, at.y, j->options);
  } else try {
    const std::vector<uint8_t> bytes = artifacts_.readTile(jobId, tile);
    dag = decodeSubDag(bytes.data(), bytes.size(), "tile " + std::to_string(tile) + " of job " + jobId,
                       j->options.compress != CompressMode::None, j->options.hash);
  } catch (const InputError& e) {
    throw TileUnreadable(e.what());
  }
  m.merger->add(std::move(dag));
  ++m.merged;
  failpoint("merge-step");
  m.peak = std::max(m.peak, m.merger->heldBytes());
  store_.addStageSeconds(jobId, {{"merge", secondsSince(start)}});
  if (m.merged == j->tilesTotal) {
    finishJob(*j, m);
    merges_.erase(jobId);
  }
}

void MergeScheduler::finishJob(const JobRecord& j, JobMerge& m) {
  auto start = std::chrono::steady_clock::now();
  CpvsArtifact art;
  art.grid = j.grid;
  art.options = j.options;
  art.sceneHash = parseHashHex(j.geometryHash, "geometry hash");
  art.receiverHash = j.receiverHash;
  art.plan = j.plan;
  art.dag = assembleRoots(*m.merger->finish(), art.options.hash, art.options.compress);
  store_.addStageSeconds(j.id, {{"merge", secondsSince(start)}});
  start = std::chrono::steady_clock::now();
  const std::vector<uint8_t> file = encodeCpvs(art, true);
  artifacts_.writeArtifact(j.id, file);
  failpoint("artifact-written");
  const std::string checksum = contentHash(file.data(), file.size()).hex();
  store_.addStageSeconds(j.id, {{"write", secondsSince(start)}});
  if (!store_.finishJob(j.id, art.dag.bytes(), file.size(), m.peak, checksum, nowMs())) {
    // Cancelled or failed while this merge wrote the artifact: the first end stands.
    artifacts_.removeArtifact(j.id);
    artifacts_.removeTiles(j.id);
    return;
  }
  // Only now that the artifact and its acknowledgement are durable.
  artifacts_.removeTiles(j.id);
  spdlog::info("job {} done: {} bytes (file {}), peak merge memory {} bytes", j.id, art.dag.bytes(), file.size(),
               m.peak);
  feed_.notify();
}

}  // namespace cpvs::server
