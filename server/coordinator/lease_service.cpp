#include "coordinator/lease_service.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "coordinator/bundle_job.h"
#include "coordinator/dag_mh_job.h"
#include "coordinator/clock.h"
#include "coordinator/failpoint.h"
#include "coordinator/stored_spec.h"
#include "cpvs/bake/tile_plan.h"
#include "cpvs/base/error.h"
#include "cpvs/base/text.h"
#include "cpvs/io/sub_dag_file.h"
#include "cpvs/net/convert.h"
#include "cpvs/net/error_kind.h"

namespace cpvs::server {

using net::ErrorKind;
using net::FarmError;

namespace {

/// The reaper's period, and how far past it a round may come (or the wall clock may move
/// against the steady one) before the coordinator counts itself paused (R10).
constexpr int64_t kReaperTickMs = 250, kPauseMs = 1000;

int64_t steadyMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// A sub-DAG result: it decodes and holds exactly the tile's blocks. InputError naming
// `source` otherwise.
void checkSubDag(const JobRecord& j, uint64_t tile, const std::string& encoded, const std::string& source) {
  const Dag dag = decodeSubDag(reinterpret_cast<const uint8_t*>(encoded.data()), encoded.size(), source,
                               j.options.compress != CompressMode::None, j.options.hash);
  const GridTiles tiles = tilesOf(j);
  const GridTiles::At at = tiles.at(tile);
  const TilePlan& plan = tiles.plan(at.grid);
  if (dag.log2Resolution != plan.log2Resolution())
    throw InputError(source + ": resolution does not match the " + (j.isBundle() ? "tile's grid" : "job"));
  checkTileRoots(dag, at.tile.x, at.tile.y, plan.log2TileSize(), source);
}

const char* failKindName(pb::FailKind kind) {
  switch (kind) {
    case pb::FAIL_INTERRUPTED: return "interrupted";
    case pb::FAIL_WORKER: return "the worker's own trouble";
    case pb::FAIL_SCENE_DAMAGED: return "the scene arrived damaged";
    default: return "tile fault";
  }
}

}  // namespace

LeaseService::LeaseService(FarmStore& store, SceneStore& scenes, ArtifactStore& artifacts, MergeScheduler& merges,
                           JobService& jobs, ChangeFeed& feed, FarmMetrics& metrics, LeaseRules rules)
    : store_(store),
      scenes_(scenes),
      artifacts_(artifacts),
      merges_(merges),
      jobs_(jobs),
      feed_(feed),
      metrics_(metrics),
      rules_(rules) {}

void LeaseService::start() {
  // Workers could not renew while the coordinator was down: every lease still out gets a
  // whole lease length from now before the reaper may take it back (R10).
  store_.extendLeasesTo(leaseClockMs() + int64_t(rules_.leaseSeconds * 1000));
  lastRoundSteadyMs_ = steadyMs();
  reaper_ = std::thread([this] { reaperLoop(); });
}

double LeaseService::secondsSinceReaperRound() const { return double(steadyMs() - lastRoundSteadyMs_) / 1000.0; }

void LeaseService::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (reaper_.joinable()) reaper_.join();
}

pb::TileLease LeaseService::lease(const std::string& workerId) {
  if (workerId.empty() || workerId.size() > 128)
    throw FarmError(ErrorKind::InvalidArgument, "worker_id must be 1..128 characters");
  pb::TileLease out;
  if (const int64_t wait = quarantinedForMs(workerId); wait > 0) {
    out.set_granted(false);
    out.set_retry_after_ms(uint32_t(std::min<int64_t>(wait, 5000)));
    return out;
  }
  int64_t now = leaseClockMs();
  int64_t deadline = now + int64_t(rules_.leaseSeconds * 1000);
  auto l = store_.leaseNextTile(workerId, randomId("l"), now, deadline);
  if (!l) {
    out.set_granted(false);
    out.set_retry_after_ms(500);
    return out;
  }
  auto j = store_.job(l->jobId, false);
  out.set_granted(true);
  out.set_lease_id(l->leaseId);
  out.set_job_id(l->jobId);
  out.set_tile_index(l->tile);
  const GridTiles::At at = tilesOf(*j).at(l->tile);
  out.set_tile_x(at.tile.x);
  out.set_tile_y(at.tile.y);
  out.set_scene_hash(j->sceneHash);
  const JobGrid& g = j->grids.at(at.grid);
  *out.mutable_grid() = net::toProto(g.grid);
  if (j->isBundle()) {
    out.set_grid_index(at.grid);
    out.set_light(g.light);
    pb::LightList lights;
    try {
      lights = lightListOf(*j);
    } catch (const FormatError&) {
    }
    if (g.light >= uint32_t(lights.lights_size())) {
      // Damaged in the store: no tile of the job can bake, so it fails instead of
      // leasing the same tile until its attempts run out.
      const std::string why = "its stored lights do not hold light " + std::to_string(g.light);
      jobs_.failJob(l->jobId, why);
      throw FarmError(ErrorKind::Internal, "job " + j->id + ": " + why);
    }
    *out.mutable_exclude() = lights.lights(int(g.light)).exclude();
  }
  *out.mutable_options() = net::toProto(j->options);
  if (isDagMhJob(*j)) out.set_format(pb::ARTIFACT_FORMAT_DAG_MH);
  if (j->options.receivers != ReceiverKind::Everywhere) {
    // The declaration (volume, boxes, cameras) lives in the spec as submitted, not in the typed columns.
    *out.mutable_options()->mutable_receivers() = bakeSpecOf(*j).options().receivers();
  }
  out.set_deadline_unix_ms(deadline);
  out.set_lease_ms(uint32_t(deadline - now));
  metrics_.leaseGranted();
  feed_.notify();
  return out;
}

void LeaseService::checkResultLease(const std::string& leaseId) {
  if (!store_.lease(leaseId)) throw FarmError(ErrorKind::NotFound, "no lease " + leaseId);
}

pb::RenewReply LeaseService::renew(const std::string& leaseId) {
  pb::RenewReply r;
  const int64_t now = leaseClockMs();
  int64_t deadline = now + int64_t(rules_.leaseSeconds * 1000);
  // A bake that keeps renewing without finishing (hung) gets no renewal past the longest
  // a tile may take: its lease then expires and the tile goes to another worker (R12).
  const auto l = store_.lease(leaseId);
  const int64_t ceiling = l ? l->grantedMs + int64_t(rules_.maxTileSeconds * 1000) : 0;
  if (!l || now >= ceiling) {
    r.set_valid(false);
    return r;
  }
  deadline = std::min(deadline, ceiling);
  try {
    r.set_valid(store_.renewLease(leaseId, deadline));
  } catch (const StoreUnavailable&) {
    // The store cannot record it now (a full disk): the renewal is kept here and recorded
    // by the reaper before it expires anything, so the worker loses nothing (R9).
    std::lock_guard lock(pendingMutex_);
    if (pendingRenewals_.size() < 100000) pendingRenewals_[leaseId] = deadline;
    r.set_valid(true);
  }
  r.set_deadline_unix_ms(r.valid() ? deadline : 0);
  r.set_lease_ms(r.valid() ? uint32_t(deadline - now) : 0);
  return r;
}

bool LeaseService::completeTile(const std::string& leaseId, const std::string& encoded,
                                const std::map<std::string, double>& stages, bool reused) {
  const bool taken = takeResult(leaseId, encoded, stages, reused);
  metrics_.tileReturned(taken, stages, encoded.size());
  return taken;
}

bool LeaseService::takeResult(const std::string& leaseId, const std::string& encoded,
                              const std::map<std::string, double>& stages, bool reused) {
  auto l = store_.lease(leaseId);
  if (!l) throw FarmError(ErrorKind::NotFound, "no lease " + leaseId);
  auto j = store_.job(l->jobId, false);
  if (!j || isFinal(j->state)) return false;
  std::string source = "tile " + std::to_string(l->tile) + " of job " + l->jobId;
  try {
    if (isDagMhJob(*j)) {
      if (encoded.empty()) throw InputError(source + ": an empty result");
      dagMhPartsOf(*j, l->tile, std::vector<uint8_t>(encoded.begin(), encoded.end()), source);
    } else {
      checkSubDag(*j, l->tile, encoded, source);
    }
  } catch (const InputError& e) {
    throw FarmError(ErrorKind::InvalidArgument, std::string("rejected result: ") + e.what());
  }
  // The file first, then the acknowledgement: a tile marked done always has its bytes.
  // Both under one lock, and only for a tile still waiting for its result: a declined
  // result (a late or duplicate lease) must not replace the file of the one taken, which
  // the merge, and a restart's merge, read; and two results for one tile must not write
  // the same temporary file at once.
  std::lock_guard resultLock(jobs_.resultMutex());
  auto state = store_.tileState(l->jobId, l->tile);
  if (!state || (*state != TileState::Queued && *state != TileState::Leased)) return false;
  std::vector<uint8_t> bytes(encoded.begin(), encoded.end());
  try {
    artifacts_.writeTile(l->jobId, l->tile, bytes);
  } catch (const InputError& e) {
    // The coordinator's own disk (full, read-only): not the worker's fault. The tile stays
    // leased and the worker sends the same result again later (R9).
    spdlog::warn("tile {} of job {}: cannot store its result now: {}", l->tile, l->jobId, e.what());
    throw FarmError(ErrorKind::Unavailable, "the coordinator cannot store the result now (its disk); send it again");
  }
  failpoint("tile-written");
  double seconds = 0;  // the worker's, what the ETA fits
  for (const auto& [stage, s] : stages) seconds += s;
  if (!store_.completeTile(l->jobId, l->tile, seconds, reused)) return false;
  failpoint("tile-acknowledged");
  {
    std::lock_guard workersLock(workersMutex_);
    workers_.erase(l->workerId);  // a worker that delivers is forgiven its failures
  }
  store_.addStageSeconds(l->jobId, stages);
  if (store_.outstandingTiles(l->jobId) == 0) store_.setJobState(l->jobId, JobState::Merging, "", nowMs());
  merges_.mergeTile(l->jobId, l->tile);
  feed_.notify();
  return true;
}

void LeaseService::failTile(const std::string& leaseId, const std::string& reason, pb::FailKind kind) {
  auto l = store_.lease(leaseId);
  if (!l) throw FarmError(ErrorKind::NotFound, "no lease " + leaseId);
  if (!pb::FailKind_IsValid(kind)) kind = pb::FAIL_TILE;
  if (kind == pb::FAIL_SCENE_DAMAGED) {
    // Damaged on the way, in the worker's cache, or on the coordinator's own disk: only the
    // last is the job's business. A stored copy that fails its hash is forgotten, so that
    // the next submit uploads the scene again (R4).
    const auto j = store_.job(l->jobId);
    if (j && !scenes_.verifyStored(j->sceneHash)) {
      if (!store_.requeueTile(leaseId, reason, false)) return;
      jobs_.failJob(l->jobId, "the coordinator's stored copy of scene " + j->sceneHash +
                                  " was damaged and is forgotten: submit the job again to upload the scene");
      metrics_.tileFailed("scene");
      feed_.notify();
      return;
    }
    kind = pb::FAIL_WORKER;
  }
  const bool counts = kind == pb::FAIL_TILE;
  const auto attempts = store_.requeueTile(leaseId, reason, counts);
  if (!attempts) return;  // no longer the tile's current lease: its tile is someone else's
  metrics_.tileFailed(kind == pb::FAIL_TILE ? "tile" : kind == pb::FAIL_WORKER ? "worker" : "interrupted");
  // Worker ids and reasons are the workers' text: logged escaped (R26).
  spdlog::warn("tile {} of job {} given back by {} ({}, attempt {} counted): {}", l->tile, l->jobId,
               loggable(l->workerId), failKindName(kind), *attempts, loggable(reason));
  if (kind != pb::FAIL_INTERRUPTED) noteWorkerFailure(l->workerId, kind == pb::FAIL_WORKER);
  if (counts && *attempts >= rules_.maxAttempts)
    jobs_.failJob(l->jobId, "tile " + std::to_string(l->tile) + " failed " + std::to_string(*attempts) + " times: " + reason);
  feed_.notify();
}

int64_t LeaseService::quarantinedForMs(const std::string& workerId) {
  std::lock_guard lock(workersMutex_);
  const auto it = workers_.find(workerId);
  if (it == workers_.end()) return 0;
  const auto left = it->second.until - std::chrono::steady_clock::now();
  return std::max<int64_t>(0, std::chrono::duration_cast<std::chrono::milliseconds>(left).count());
}

void LeaseService::noteWorkerFailure(const std::string& workerId, bool quarantineNow) {
  std::lock_guard lock(workersMutex_);
  if (workers_.size() >= 10000 && !workers_.count(workerId)) workers_.clear();
  WorkerRecord& w = workers_[workerId];
  if (!quarantineNow && ++w.failuresInARow < kQuarantineAfterFailures) return;
  w.failuresInARow = 0;
  const double seconds = std::min(kMaxQuarantineSeconds, rules_.quarantineSeconds * std::ldexp(1.0, std::min(w.quarantines, 20)));
  ++w.quarantines;
  w.until = std::chrono::steady_clock::now() + std::chrono::milliseconds(int64_t(seconds * 1000));
  spdlog::warn("worker {} gets no tile for {:.0f} s: {}", loggable(workerId), seconds,
               quarantineNow ? "it reported trouble of its own" : "it failed 3 tiles in a row");
}

void LeaseService::reaperLoop() {
  auto lastSteady = std::chrono::steady_clock::now();
  for (;;) {
    {
      std::unique_lock lock(mutex_);
      wake_.wait_for(lock, std::chrono::milliseconds(kReaperTickMs), [&] { return stopping_; });
      if (stopping_) return;
    }
    // A store that fails now (a busy or full disk) fails this round, not the process
    // (R9): the leases stay in the store and the next round expires them.
    try {
      // Deadlines are on the lease clock (steady: a step of the wall clock does not move
      // it), but what a worker is owed is time the coordinator was there to renew: a
      // pause of this process (SIGSTOP, a stalled VM, a store held busy) moves every
      // deadline with it, so no lease its worker kept renewing expires for it (R10).
      const auto steadyNow = std::chrono::steady_clock::now();
      const int64_t steadyGap = std::chrono::duration_cast<std::chrono::milliseconds>(steadyNow - lastSteady).count();
      int64_t shift = 0;
      if (steadyGap > kReaperTickMs + kPauseMs) shift += steadyGap - kReaperTickMs;
      // A store that could not be written (a full disk) counts as a pause too: renewals
      // failed meanwhile, and the time since the last round that went through is owed.
      if (shift != 0) {
        store_.shiftLeaseDeadlines(shift);
        spdlog::warn("leases could not be kept for {} ms (the coordinator paused or its store unavailable): every "
                     "lease moved {} ms",
                     steadyGap, shift);
        lastSteady = steadyNow;
      }
      {
        std::map<std::string, int64_t> pending;
        {
          std::lock_guard lock(pendingMutex_);
          pending.swap(pendingRenewals_);
        }
        for (auto it = pending.begin(); it != pending.end(); it = pending.erase(it)) {
          try {
            store_.renewLease(it->first, it->second);
          } catch (const StoreUnavailable&) {
            std::lock_guard lock(pendingMutex_);
            for (const auto& [lease, deadline] : pending)
              pendingRenewals_.emplace(lease, deadline);  // a newer renewal meanwhile wins
            throw;
          }
        }
      }
      const auto expired = store_.expireLeases(leaseClockMs());
      metrics_.leasesExpired(expired.size());
      for (const auto& [jobId, tile, attempts] : expired) {
        spdlog::warn("lease on tile {} of job {} expired (attempt {})", tile, jobId, attempts);
        if (attempts >= rules_.maxAttempts)
          jobs_.failJob(jobId, "tile " + std::to_string(tile) + ": lease expired " + std::to_string(attempts) + " times");
        feed_.notify();
      }
      lastSteady = steadyNow;
      lastRoundSteadyMs_ = steadyMs();
    } catch (const StoreUnavailable& e) {
      spdlog::warn("expiring leases waits for the store: {}", e.what());
    } catch (const std::exception& e) {
      spdlog::error("expiring leases failed, retrying: {}", e.what());
    }
  }
}

}  // namespace cpvs::server
