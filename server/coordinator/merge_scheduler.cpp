#include "coordinator/merge_scheduler.h"

#include <spdlog/spdlog.h>

#include "coordinator/bundle_job.h"
#include "coordinator/dag_mh_job.h"
#include "coordinator/failpoint.h"
#include "cpvs/bake/bake.h"
#include "cpvs/bake/tile_plan.h"
#include "cpvs/base/error.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/progress.h"
#include "cpvs/dag/packed_layout.h"
#include "cpvs/psv/translucent_tree.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/psv/translucent_tree.h"
#include "cpvs/io/sub_dag_file.h"
#include "cpvs/v1/farm.pb.h"
#include "coordinator/clock.h"
#include "coordinator/stored_spec.h"

namespace cpvs::server {

MergeScheduler::MergeScheduler(FarmStore& store, ArtifactStore& artifacts, ChangeFeed& feed, FarmMetrics& metrics,
                               FailJob failJob, LoadScene loadScene)
    : store_(store),
      artifacts_(artifacts),
      feed_(feed),
      metrics_(metrics),
      failJob_(std::move(failJob)),
      loadScene_(std::move(loadScene)) {}

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

void MergeScheduler::retryLater(Item item) {
  std::lock_guard lock(mutex_);
  later_.emplace_back(std::chrono::steady_clock::now() + std::chrono::seconds(1), std::move(item));
}

void MergeScheduler::mergeTile(const std::string& jobId, uint64_t tile) { push({Item::Kind::MergeTile, jobId, tile}); }

void MergeScheduler::removeTiles(const std::string& jobId) { push({Item::Kind::RemoveTiles, jobId, 0}); }

size_t MergeScheduler::backlog() {
  std::lock_guard lock(mutex_);
  return queue_.size() + later_.size();
}

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
      for (;;) {
        if (stopping_) return;
        const auto now = std::chrono::steady_clock::now();
        auto next = now + std::chrono::hours(1);
        for (auto it = later_.begin(); it != later_.end();) {
          if (it->first <= now) {
            queue_.push_back(std::move(it->second));
            it = later_.erase(it);
          } else {
            next = std::min(next, it->first);
            ++it;
          }
        }
        if (!queue_.empty()) break;
        wake_.wait_until(lock, next);
      }
      item = std::move(queue_.front());
      queue_.pop_front();
    }
    if (item.kind == Item::Kind::RemoveTiles) {
      merges_.erase(item.jobId);
      artifacts_.removeTiles(item.jobId);
      continue;
    }
    try {
      if (item.kind == Item::Kind::WriteArtifact) {
        const auto j = store_.job(item.jobId);
        if (!j || isFinal(j->state) || finishJob(*j, merges_[item.jobId])) merges_.erase(item.jobId);
        continue;
      }
      mergeOne(item.jobId, item.tile);
    } catch (const StoreUnavailable& e) {
      // Read before anything was merged (the merger changes only once the tile is in):
      // the same item again, later.
      spdlog::warn("job {}: {}; merging again in 1 s", item.jobId, e.what());
      retryLater(item);
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
  auto j = store_.job(jobId, false);
  if (!j || isFinal(j->state)) {
    merges_.erase(jobId);
    return;
  }
  JobMerge& m = merges_[jobId];
  if (isDagMhJob(*j)) {
    mergeDagMhTile(*j, m, tile);
    return;
  }
  const GridTiles tiles = tilesOf(*j);
  if (m.grids.empty()) m.grids.resize(tiles.grids());
  const GridTiles::At at = tiles.at(tile);
  const TilePlan& plan = tiles.plan(at.grid);
  GridMerge& g = m.grids[at.grid];
  CPVS_CHECK(!g.dag);  // every tile is merged once: a grid is assembled after its last
  if (!g.merger) g.merger = std::make_unique<StreamingMerger>(j->options.compress);
  const auto start = std::chrono::steady_clock::now();
  Dag dag;
  const std::optional<TileState> state = store_.tileState(jobId, tile);
  if (state == TileState::Untouched || state == TileState::Unread) {
    dag = bakeUntouchedTile(plan.log2Resolution(), at.tile.x, at.tile.y, j->options);
  } else try {
    const std::vector<uint8_t> bytes = artifacts_.readTile(jobId, tile);
    dag = decodeSubDag(bytes.data(), bytes.size(), "tile " + std::to_string(tile) + " of job " + jobId,
                       j->options.compress != CompressMode::None, j->options.hash);
  } catch (const InputError& e) {
    throw TileUnreadable(e.what());
  }
  g.merger->add(std::move(dag));
  ++g.merged;
  ++m.merged;
  failpoint("merge-step");
  uint64_t held = 0;
  for (const GridMerge& other : m.grids) held += other.merger ? other.merger->heldBytes() : other.dag ? other.dag->bytes() : 0;
  m.peak = std::max(m.peak, held);
  if (g.merged == plan.count()) {
    // The grid's levels above its tile roots, as bakeGrid assembles them.
    g.dag = assembleRoots(*g.merger->finish(), j->options.hash, j->options.compress);
    g.merger.reset();
  }
  const double seconds = secondsSince(start);
  metrics_.tileMerged(seconds);
  try {
    store_.addStageSeconds(jobId, {{"merge", seconds}});
  } catch (const StoreUnavailable&) {
    // Statistics only: the tile is merged, and must not be merged again.
  }
  if (m.merged == j->tilesTotal && finishJob(*j, m)) merges_.erase(jobId);
}

void MergeScheduler::mergeDagMhTile(const JobRecord& j, JobMerge& m, uint64_t tile) {
  if (!m.dagMh) m.dagMh = dagMhBuilderOf(j);
  CPVS_CHECK(!m.dagMhDone);  // every tile is merged once
  const auto start = std::chrono::steady_clock::now();
  const std::optional<TileState> state = store_.tileState(j.id, tile);
  const bool lit = state == TileState::Untouched || state == TileState::Unread;
  std::vector<DagMhTile> parts;
  try {
    const std::string source = "tile " + std::to_string(tile) + " of job " + j.id;
    parts = dagMhPartsOf(j, tile, lit ? std::vector<uint8_t>{} : artifacts_.readTile(j.id, tile), source);
  } catch (const InputError& e) {
    throw TileUnreadable(e.what());
  }
  for (DagMhTile& p : parts) m.dagMh->addTile(std::move(p));
  ++m.merged;
  failpoint("merge-step");
  m.peak = std::max(m.peak, m.dagMh->heldBytes());
  double seconds = secondsSince(start);
  if (m.merged == j.tilesTotal) {
    // The levels above the tiles, the layout, the values chunked, the skip list.
    const auto finish = std::chrono::steady_clock::now();
    m.dagMhDone = m.dagMh->finish();
    m.dagMh.reset();
    // Parts from workers, each checked, could still make a whole no reader takes: the
    // job fails rather than writing a file its clients refuse.
    validateDagMh(*m.dagMhDone, "job " + j.id + "'s DAG-MH");
    seconds += secondsSince(finish);
  }
  metrics_.tileMerged(seconds);
  try {
    store_.addStageSeconds(j.id, {{"merge", seconds}});
  } catch (const StoreUnavailable&) {
  }
  if (m.merged == j.tilesTotal && finishJob(j, m)) merges_.erase(j.id);
}

bool MergeScheduler::finishJob(const JobRecord& j, JobMerge& m) {
  if (m.file.empty() && m.dagMhDone) {  // a DAG-MH job's .dmh
    const auto start = std::chrono::steady_clock::now();
    m.dagBytes = m.dagMhDone->bytes();
    m.file = dmhFileOf(j, std::move(*m.dagMhDone));
    m.dagMhDone.reset();
    try {
      store_.addStageSeconds(j.id, {{"write", secondsSince(start)}});
    } catch (const StoreUnavailable&) {
    }
  }
  if (m.file.empty()) {
    // A sun job's translucent casters (its plan records them when there are some: only then
    // is the scene read), before its DAG is taken: a store that cannot answer now is asked
    // again with nothing lost.
    std::shared_ptr<const TopTree> translucent;
    if (!j.isBundle() && j.plan.find("\"translucent\"") != std::string::npos) {
      try {
        const auto treeStart = std::chrono::steady_clock::now();
        const Scene scene = loadScene_(j.sceneHash);
        if (hasTranslucentMeshes(scene))
          translucent = std::make_shared<const TopTree>(translucentTree(scene, PsvLight::sun(sunGridOf(j).frame.dir)));
        try {
          store_.addStageSeconds(j.id, {{"translucent", secondsSince(treeStart)}});
        } catch (const StoreUnavailable&) {
        }
      } catch (const StoreUnavailable& e) {
        spdlog::warn("job {}: cannot read its scene now ({}); trying again in 1 s, its tiles kept", j.id, e.what());
        retryLater({Item::Kind::WriteArtifact, j.id, 0});
        return false;
      } catch (const std::exception& e) {
        failJob(j.id, std::string("cannot build its translucent casters' tree: ") + e.what());
        return true;
      }
    }
    auto start = std::chrono::steady_clock::now();
    std::vector<Dag> dags;
    for (GridMerge& g : m.grids) dags.push_back(std::move(*g.dag));
    m.grids.clear();
    if (!j.isBundle()) {
      CpvsArtifact art;
      art.grid = sunGridOf(j);
      art.options = j.options;
      art.sceneHash = parseHashHex(j.geometryHash, "geometry hash");
      art.receiverHash = j.receiverHash;
      art.plan = j.plan;
      art.dag = std::move(dags.at(0));
      art.translucent = std::move(translucent);
      m.dagBytes = art.dag.bytes();
      m.file = encodeCpvs(art, true);
      try {
        store_.addStageSeconds(j.id, {{"write", secondsSince(start)}});
      } catch (const StoreUnavailable&) {
      }
    } else {
      // The grids' nodes shared in grid order, as bakeLights shares them.
      const v1::BakeSpec spec = bakeSpecOf(j);
      const LightBundle bundle = bundleOf(j, std::move(dags), spec.has_pointer_grid() ? int(spec.pointer_grid()) : kMaxGridLevels);
      m.dagBytes = bundle.poolBytes;
      const double merged = secondsSince(start);
      start = std::chrono::steady_clock::now();
      m.file = encodeBundle(bundle, true);
      try {
        store_.addStageSeconds(j.id, {{"merge", merged}, {"write", secondsSince(start)}});
      } catch (const StoreUnavailable&) {
      }
    }
  }
  const auto writeStart = std::chrono::steady_clock::now();
  try {
    artifacts_.writeArtifact(j.id, m.file);
    failpoint("artifact-written");
    const std::string checksum = contentHash(m.file.data(), m.file.size()).hex();
    if (!store_.finishJob(j.id, m.dagBytes, m.file.size(), m.peak, checksum, nowMs())) {
      // Cancelled or failed while this merge wrote the artifact: the first end stands.
      artifacts_.removeArtifact(j.id);
      artifacts_.removeTiles(j.id);
      return true;
    }
  } catch (const std::exception& e) {
    // A full disk (InputError from the write) or a store that cannot commit now.
    if (!dynamic_cast<const InputError*>(&e) && !dynamic_cast<const StoreUnavailable*>(&e)) throw;
    spdlog::warn("job {}: cannot write its artifact now ({}); trying again in 1 s, its tiles kept", j.id, e.what());
    retryLater({Item::Kind::WriteArtifact, j.id, 0});
    return false;
  }
  // Only now that the artifact and its acknowledgement are durable.
  metrics_.artifactWritten(m.file.size(), secondsSince(writeStart));
  artifacts_.removeTiles(j.id);
  spdlog::info("job {} done: {} bytes (file {}), peak merge memory {} bytes", j.id, m.dagBytes, m.file.size(), m.peak);
  feed_.notify();
  return true;
}

}  // namespace cpvs::server
