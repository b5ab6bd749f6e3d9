// The coordinator's durable state in SQLite (WAL): scenes, jobs, tiles, leases. Every
// method is one transaction; the store is safe to call from any thread. A job's grid and
// options are typed columns, read without parsing anything; SQLite stays behind this
// class (the handle is only named here).
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/bake/tile_eta.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/vec3.h"
#include "cpvs/light/grid_spec.h"

struct sqlite3;

namespace cpvs::server {

/// Tile states as stored.
/// Untouched: no triangle can touch the tile (BakeScene::touchesTile); Unread: triangles
/// may touch it, but no declared receiver reads it (ReceiverSet::touchesRectangle). Both
/// are done when the job is created, never leased, merged as the all-lit sub-DAG without
/// a file.
/// The store cannot read or write now (disk full, an I/O error, busy): the same call may
/// succeed later; the caller is told to try again (UNAVAILABLE), and no work is failed.
struct StoreUnavailable : std::runtime_error {
  using std::runtime_error::runtime_error;
};

enum class TileState : int { Queued = 0, Leased = 1, Done = 2, Cancelled = 3, Untouched = 4, Unread = 5 };

/// Job states as stored: the values of cpvs.v1.JobState.
enum class JobState : int { Queued = 1, Running = 2, Merging = 3, Done = 4, Failed = 5, Cancelled = 6 };

inline bool isFinal(JobState s) { return s == JobState::Done || s == JobState::Failed || s == JobState::Cancelled; }

struct SceneRecord {
  std::string hash, fileName, geometryHash;
  uint64_t totalSize = 0, received = 0, triangles = 0;
  bool complete = false;
  std::string owner;  // the client whose upload began it ('' without tokens, or an administrator)
};

struct JobRecord;
struct TrackRecord;

/// Rewrites a job's or a track's stored spec (spec, lights, and the scene columns they
/// fill) in an older store's format to this build's; the store knows no spec format.
struct SpecRewrite {
  std::function<void(JobRecord&)> job;
  std::function<void(TrackRecord&)> track;
};

/// A job's tiles with work (triangles) known: those done with their seconds, as sums, and
/// those still to do.
struct TileCosts {
  TileCostSums done;
  uint64_t leftTiles = 0;
  double leftWork = 0;
};

struct SceneBytes {
  uint64_t uploading = 0, stored = 0;
};

/// One grid of a job (table job_grids): a sun job's one orthographic grid, or one of a
/// light bundle's perspective ones (with the cone its texels are cut off by), its light,
/// and the closest geometry the planner found (infinity: none), which a bundle's plan
/// records.
struct JobGrid {
  GridSpec grid;
  uint32_t light = 0;
  double closest = std::numeric_limits<double>::infinity();
};

struct JobRecord {
  std::string id, requestId, sceneHash, geometryHash;
  /// The request's cpvs.v1.BakeSpec as sent, one JSON document in protobuf's mapping
  /// (coordinator/stored_spec.h): shown back, compared on retries.
  std::string spec;
  std::string receiverScene;  // the scene hash of its receiver volume mesh, '' for none
  /// A light bundle's lights, a cpvs.v1.LightList in the same JSON (the scene's own
  /// included: what the artifact's light table records); empty for a sun bake.
  std::string lights;
  /// What the tiles bake, in GridTiles' order: the sun's one grid, or a bundle's.
  std::vector<JobGrid> grids;
  BakeOptions options;
  Hash128 receiverHash;  // receiverHash of the job's declaration (zero: receivers everywhere)
  std::string plan;      // planJson of the bake, made at submit: the artifact records it
  std::string owner;     // the client that submitted it (R28); '' without tokens
  JobState state = JobState::Queued;
  int priority = 0;
  int64_t createdMs = 0, startedMs = 0, finishedMs = 0;
  std::string error, artifactChecksum;
  uint64_t tilesTotal = 0, tilesDone = 0;  // the grid's and options' TilePlan; done from the tiles
  uint64_t tilesUntouched = 0;             // of tilesDone, those no triangle touches
  uint64_t tilesUnread = 0;                // of tilesDone, those no declared receiver reads
  uint64_t tilesReused = 0;                // of tilesDone, those a worker sent from its tile cache
  uint64_t bytes = 0, fileBytes = 0, peakMergeBytes = 0;
  std::map<std::string, double> stages;

  bool isBundle() const { return !lights.empty(); }
};

struct LeaseRecord {
  std::string leaseId, jobId, workerId;
  uint64_t tile = 0;
  int64_t deadlineMs = 0;  // 0 when no longer the tile's current lease
  int64_t grantedMs = 0;
};

/// A sun track (TrackService): its spec as sent, and how far it got. state holds the
/// values of cpvs.v1.TrackState.
struct TrackRecord {
  std::string id, requestId, error;
  std::string spec;       // its cpvs.v1.TrackSpec as sent, in JSON as a job's spec
  std::string sceneHash;  // the scene its keyframes bake
  std::string receiverScene;  // the scene hash of its receiver volume mesh, '' for none
  std::string owner;  // the client that created it (R28); '' without tokens
  int state = 1;
  int64_t createdMs = 0;
  uint64_t keyframesTotal = 0;  // 0: a clock, unbounded
  uint64_t nextKeyframe = 0;    // the next keyframe not yet submitted (or skipped as night)
  uint64_t published = 0, skipped = 0, latestSequence = 0;
};

/// A keyframe submitted as a job: pending until published as a version or skipped.
struct KeyframeRecord {
  std::string trackId;
  uint64_t keyframe = 0;
  int64_t instantMs = 0;
  Vec3 direction;
  std::string jobId;
  int state = 0;  // 0 pending, 1 published, 2 skipped
};

struct VersionRecord {
  std::string trackId;
  uint64_t sequence = 0, keyframe = 0;
  int64_t instantMs = 0;
  Vec3 direction;
  std::string jobId, checksum;
  uint64_t fileBytes = 0;
  int64_t publishedMs = 0;
};

class FarmStore {
 public:
  /// Opens (creating if needed) the database file. Throws std::runtime_error, also for a
  /// database of another schema version.
  /// Opens (or creates) the store at `path`, upgrading an older schema in place; specs
  /// stored before they were JSON (schema 10 and older) are rewritten by `rewrite`.
  explicit FarmStore(const std::string& path, SpecRewrite rewrite = {});
  ~FarmStore();
  FarmStore(const FarmStore&) = delete;
  FarmStore& operator=(const FarmStore&) = delete;

  // Scenes.
  std::optional<SceneRecord> scene(const std::string& hash);
  void putScene(const SceneRecord& s);
  /// The bytes of one owner's scenes: announced by uploads in progress, and stored.
  SceneBytes sceneBytesOf(const std::string& owner);
  /// Whether the store can take a write within `timeoutMs`: its lock and SQLite's write
  /// lock both free (what the health service reports, R27).
  bool responsive(int timeoutMs);
  /// Hashes of the scenes whose upload started and is not complete.
  std::vector<std::string> incompleteScenes();
  void deleteScene(const std::string& hash);
  /// Notes that a job uses the scene now (its retention counts from the last use).
  void touchScene(const std::string& hash);
  /// Forgets at most `limit` complete scenes last used before `beforeMs` that no job and
  /// no active track names; returns their hashes, whose files the caller removes.
  std::vector<std::string> pruneUnusedScenes(int64_t beforeMs, size_t limit);

  // Jobs.
  /// A job with its grids; `withCounts` adds its tile counts and stage seconds, which read
  /// every tile of the job: the lease and merge paths, once a tile, go without.
  std::optional<JobRecord> job(const std::string& id, bool withCounts = true);
  /// Tiles of the job still queued or leased (an index range, however large the job).
  uint64_t outstandingTiles(const std::string& jobId);
  std::optional<JobRecord> jobByRequest(const std::string& requestId);
  /// The job and its tiles, each in its state of `states` (one per tile: Queued, Untouched
  /// or Unread), or all Queued when `states` is empty, and with its work of `work` (the
  /// triangles that reach it, cpvs/bake/bake.h tileWork), or none known when empty.
  void createJob(const JobRecord& j, const std::vector<TileState>& states = {},
                 const std::vector<uint32_t>& work = {});
  /// What the job's tiles cost so far and what is left, for its ETA (TileEta's law).
  TileCosts tileCosts(const std::string& jobId);
  std::vector<JobRecord> jobs(bool includeFinished);
  /// At most `limit` jobs after the position (createdMs, id), oldest first: a page of a
  /// listing that stays bounded however many jobs the store holds (R16); with `owner`,
  /// only that owner's jobs and those made without one.
  static constexpr size_t kNoLimit = ~size_t(0);
  std::vector<JobRecord> jobsAfter(bool includeFinished, int64_t createdMs, const std::string& id, size_t limit,
                                   const std::optional<std::string>& owner = std::nullopt);
  /// Forgets at most `limit` jobs that ended before `beforeMs` and that no track still
  /// needs (a kept version or a pending keyframe): their rows, tiles, leases and stages, in
  /// one transaction. Returns their ids, whose files the caller removes (R16, R25).
  std::vector<std::string> pruneFinishedJobs(int64_t beforeMs, size_t limit);
  size_t activeJobCount();
  /// What the farm holds, for its metrics: jobs by state, tiles of unfinished jobs queued
  /// and leased, and the bytes of finished artifacts. A few indexed counts.
  struct Census {
    std::map<JobState, uint64_t> jobs;
    uint64_t tilesQueued = 0, tilesLeased = 0;
    uint64_t artifactBytes = 0;
  };
  Census census();
  /// Of them, those of one owner.
  size_t activeJobCount(const std::string& owner);
  void setJobState(const std::string& id, JobState s, const std::string& error, int64_t nowMs);
  /// Marks an unfinished job done with its artifact; false (and nothing changed) when the
  /// job ended meanwhile (a cancel stands).
  bool finishJob(const std::string& id, uint64_t bytes, uint64_t fileBytes, uint64_t peakMergeBytes,
                 const std::string& checksum, int64_t nowMs);
  void addStageSeconds(const std::string& id, const std::map<std::string, double>& stages);
  void setPeakMergeBytes(const std::string& id, uint64_t bytes);

  // Tiles and leases.
  /// Leases the next queued tile: highest job priority first, then a tile this worker did
  /// not fail last (a worker that fails at once does not take one tile's every attempt),
  /// then the job with the fewest tiles out on lease (fair sharing), then the oldest job,
  /// then tile order.
  std::optional<LeaseRecord> leaseNextTile(const std::string& workerId, const std::string& leaseId, int64_t nowMs,
                                           int64_t deadlineMs);
  std::optional<LeaseRecord> lease(const std::string& leaseId);
  /// Extends a lease that is still the tile's current one; false otherwise.
  bool renewLease(const std::string& leaseId, int64_t deadlineMs);
  /// The tile's state; nullopt for a tile the job does not have.
  std::optional<TileState> tileState(const std::string& jobId, uint64_t tile);
  /// Marks the tile done unless it already is, with the seconds its worker spent on it;
  /// returns whether this call did.
  bool completeTile(const std::string& jobId, uint64_t tile, double seconds = 0, bool reused = false);
  /// Returns the tile of a failed lease to the queue when that lease is still the tile's
  /// current one, noting its worker as the one that failed it last; returns the tile's
  /// attempts so far (the lease's not counted when `counts` is false), nullopt when the
  /// lease was not current.
  std::optional<int> requeueTile(const std::string& leaseId, const std::string& error, bool counts = true);
  /// Every lease out gets at least until `deadlineMs` (the grace after a restart, during
  /// which workers could not renew).
  void extendLeasesTo(int64_t deadlineMs);
  /// Moves every lease's deadline by `deltaMs` (a pause of the coordinator, or a step of
  /// its wall clock, that workers could not renew through).
  void shiftLeaseDeadlines(int64_t deltaMs);
  /// Returns an acknowledged tile whose result cannot be read back to the queue (its
  /// attempts kept); the job goes back to running.
  void requeueDoneTile(const std::string& jobId, uint64_t tile, const std::string& error);
  /// Tiles whose current lease expired before nowMs, returned to the queue: (job, tile, attempts).
  std::vector<std::tuple<std::string, uint64_t, int>> expireLeases(int64_t nowMs);
  /// Tiles done (acknowledged or untouched), in order.
  std::vector<uint64_t> doneTiles(const std::string& jobId);
  int tileAttempts(const std::string& jobId, uint64_t tile);
  void cancelTiles(const std::string& jobId);

  // Sun tracks, their keyframes and published versions.
  void createTrack(const TrackRecord& t);
  std::optional<TrackRecord> track(const std::string& id);
  std::optional<TrackRecord> trackByRequest(const std::string& requestId);
  std::vector<TrackRecord> tracks(bool includeEnded);
  void setTrackState(const std::string& id, int state, const std::string& error);
  /// Records a submitted keyframe and moves the track's next keyframe past it.
  void addKeyframe(const KeyframeRecord& k);
  /// Moves the next keyframe to `next` without submitting the ones before it (night, or
  /// behind a clock).
  void advanceNextKeyframe(const std::string& trackId, uint64_t next);
  std::vector<KeyframeRecord> pendingKeyframes(const std::string& trackId);
  void skipKeyframe(const std::string& trackId, uint64_t keyframe);
  /// Publishes a pending keyframe as the track's next version (sequence latest + 1) and
  /// drops versions older than the newest `keep`; returns the version.
  VersionRecord publishKeyframe(const std::string& trackId, uint64_t keyframe, const std::string& checksum,
                                uint64_t fileBytes, uint64_t keep, int64_t nowMs);
  /// The first kept version after `sequence`.
  std::optional<VersionRecord> versionAfter(const std::string& trackId, uint64_t sequence);
  /// Whether an active track other than `trackId` still waits on the job.
  bool jobWantedByAnotherTrack(const std::string& jobId, const std::string& trackId);

 private:
  void exec(const char* sql);
  /// Fills the grids of a job read from its row and, `withCounts`, its tile counts and
  /// stage seconds (under mutex_).
  void fillJobCounts(JobRecord& j, bool withCounts = true);
  sqlite3* db_ = nullptr;
  std::timed_mutex mutex_;
};

}  // namespace cpvs::server
