#include "store/farm_store.h"

#include <chrono>
#include <cmath>

#include <sqlite3.h>

#include <limits>
#include <stdexcept>

#include "cpvs/base/error.h"

namespace cpvs::server {

namespace {

/// A prepared statement with typed binding and reading; finalized on scope exit.
class Statement {
 public:
  Statement(sqlite3* db, const char* sql) : db_(db) {
    if (sqlite3_prepare_v2(db, sql, -1, &st_, nullptr) != SQLITE_OK)
      throw std::runtime_error(std::string("sqlite prepare: ") + sqlite3_errmsg(db) + " in: " + sql);
  }
  ~Statement() { sqlite3_finalize(st_); }
  Statement& bind(int i, const std::string& v) {
    sqlite3_bind_blob(st_, i, v.data(), int(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Statement& text(int i, const std::string& v) {
    sqlite3_bind_text(st_, i, v.data(), int(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Statement& bind(int i, int64_t v) {
    sqlite3_bind_int64(st_, i, v);
    return *this;
  }
  Statement& bind(int i, double v) {
    sqlite3_bind_double(st_, i, v);
    return *this;
  }
  /// Steps once: true while a row is available.
  bool step() {
    int rc = sqlite3_step(st_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    // A full disk, an I/O error, a store held busy: the same request may succeed later,
    // and nobody's work is at fault (R9).
    const int primary = rc & 0xff;
    if (primary == SQLITE_FULL || primary == SQLITE_IOERR || primary == SQLITE_BUSY || primary == SQLITE_LOCKED)
      throw StoreUnavailable(std::string("the job store cannot write now: ") + sqlite3_errmsg(db_));
    throw std::runtime_error(std::string("sqlite step: ") + sqlite3_errmsg(db_));
  }
  void run() {
    while (step()) {
    }
  }
  /// Ready to run again with new bindings.
  void reset() {
    sqlite3_reset(st_);
    sqlite3_clear_bindings(st_);
  }
  int64_t i64(int c) const { return sqlite3_column_int64(st_, c); }
  bool isNull(int c) const { return sqlite3_column_type(st_, c) == SQLITE_NULL; }
  double f64(int c) const { return sqlite3_column_double(st_, c); }
  std::string str(int c) const {
    const void* p = sqlite3_column_blob(st_, c);
    int n = sqlite3_column_bytes(st_, c);
    return p ? std::string(static_cast<const char*>(p), size_t(n)) : std::string();
  }

 private:
  sqlite3* db_;
  sqlite3_stmt* st_ = nullptr;
};

/// BEGIN IMMEDIATE ... COMMIT, rolled back if an exception leaves the scope.
class Transaction {
 public:
  explicit Transaction(sqlite3* db) : db_(db) { Statement(db, "BEGIN IMMEDIATE").run(); }
  void commit() {
    Statement(db_, "COMMIT").run();
    done_ = true;
  }
  ~Transaction() {
    if (!done_) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
  }

 private:
  sqlite3* db_;
  bool done_ = false;
};

constexpr const char* kJobColumns =
    "id, request_id, scene_hash, geometry_hash, spec, state, priority, created_ms, started_ms, finished_ms, error, "
    "artifact_checksum, tiles_total, bytes, file_bytes, peak_merge_bytes, "
    "closed, exit_mode, cull, compress, undefined_rule, log2_tile_size, hash_kind, renderer, receivers, receiver_pcf, "
    "receiver_hash, plan, owner, lights, receiver_scene";
constexpr int kJobColumnCount = 31;

/// The SQL parameters of an INSERT of n columns: "?, ?, ..., ?".
std::string parameterMarks(int n) {
  std::string out;
  for (int i = 0; i < n; ++i) out += i ? ", ?" : "?";
  return out;
}
constexpr int kOptionsColumn = 16;

/// The schema this build writes (PRAGMA user_version). 2: typed grid and option columns;
/// 3: the renderer column (a version 2 store is upgraded in place: its jobs were Embree's);
/// 4: sun tracks, keyframes and versions (tables added to a version 2 or 3 store);
/// 5: the receiver declaration's columns and the plan (added to a version 2 to 4 store:
/// receivers everywhere, no plan recorded); 6: the worker that failed a tile last
/// (added to a version 2 to 5 store); 7: the owner of jobs and tracks (R28; added to a
/// version 2 to 6 store as '', made without tokens: every client sees them) and when a
/// scene was last used (for its retention; now, for the scenes of an upgraded store);
/// 8: light bundles, their lights (jobs.lights) and grids (job_grids), added to a version
/// 2 to 7 store (whose jobs are sun bakes); 9: every job's grids in job_grids, of either
/// projection (a sun job's one orthographic grid moved there from the jobs table's
/// columns when a version 2 to 8 store is upgraded); 10: the client that began each
/// scene's upload (scenes.owner, for the per-client upload quotas; '' in an upgraded store);
/// 11: specs and lights as JSON documents (protobuf's mapping) rather than serialized
/// protobuf, and the scenes they name in columns of their own (jobs.receiver_scene,
/// tracks.scene_hash and receiver_scene), not found by searching the specs' bytes; 12: each tile's work (the
/// triangles that reach it) and the seconds its worker spent, for the ETA (0 in an
/// upgraded store: its jobs' ETA counts tiles); 13: whether a worker sent each tile from
/// its tile cache (tiles.reused; 0 in an upgraded store); 14: a grid's depth slices
/// (job_grids.depth_slices; 0, a cubic grid, in an upgraded store).
constexpr int kSchemaVersion = 14;

Vec3 readVec(const Statement& s, int c) { return {s.f64(c), s.f64(c + 1), s.f64(c + 2)}; }

JobRecord readJob(const Statement& s) {
  JobRecord j;
  j.id = s.str(0);
  j.requestId = s.str(1);
  j.sceneHash = s.str(2);
  j.geometryHash = s.str(3);
  j.spec = s.str(4);
  j.state = JobState(s.i64(5));
  j.priority = int(s.i64(6));
  j.createdMs = s.i64(7);
  j.startedMs = s.i64(8);
  j.finishedMs = s.i64(9);
  j.error = s.str(10);
  j.artifactChecksum = s.str(11);
  j.tilesTotal = uint64_t(s.i64(12));
  j.bytes = uint64_t(s.i64(13));
  j.fileBytes = uint64_t(s.i64(14));
  j.peakMergeBytes = uint64_t(s.i64(15));
  BakeOptions& o = j.options;
  const int c = kOptionsColumn;
  o.closed = ClosedMode(s.i64(c));
  o.exit = ExitMode(s.i64(c + 1));
  o.cull = s.i64(c + 2) != 0;
  o.compress = CompressMode(s.i64(c + 3));
  o.undefinedRule = UndefinedRule(s.i64(c + 4));
  o.log2TileSize = int(s.i64(c + 5));
  o.hash = HashKind(s.i64(c + 6));
  o.renderer = Renderer(s.i64(c + 7));
  o.receivers = ReceiverKind(s.i64(c + 8));
  o.receiverPcf = uint8_t(s.i64(c + 9));
  if (!s.str(c + 10).empty()) j.receiverHash = parseHashHex(s.str(c + 10), "the job's receiver hash");
  j.plan = s.str(c + 11);
  j.owner = s.str(c + 12);
  j.lights = s.str(c + 13);
  j.receiverScene = s.str(c + 14);
  return j;
}

void bindJob(Statement& s, const JobRecord& j) {
  s.text(1, j.id).text(2, j.requestId).text(3, j.sceneHash).text(4, j.geometryHash).text(5, j.spec);
  s.bind(6, int64_t(j.state)).bind(7, int64_t(j.priority)).bind(8, j.createdMs).bind(9, j.startedMs);
  s.bind(10, j.finishedMs).text(11, j.error).text(12, j.artifactChecksum).bind(13, int64_t(j.tilesTotal));
  s.bind(14, int64_t(0)).bind(15, int64_t(0)).bind(16, int64_t(0));
  int c = kOptionsColumn + 1;
  const BakeOptions& o = j.options;
  for (int64_t v : {int64_t(o.closed), int64_t(o.exit), int64_t(o.cull), int64_t(o.compress),
                    int64_t(o.undefinedRule), int64_t(o.log2TileSize), int64_t(o.hash), int64_t(o.renderer),
                    int64_t(o.receivers), int64_t(o.receiverPcf)})
    s.bind(c++, v);
  s.text(c++, j.receiverHash == Hash128{} ? std::string() : j.receiverHash.hex());
  s.text(c++, j.plan);
  s.text(c++, j.owner);
  s.text(c++, j.lights);
  s.text(c++, j.receiverScene);
}

constexpr const char* kGridColumns =
    "job_id, grid, light, log2_resolution, position_x, position_y, position_z, dir_x, dir_y, dir_z, u_x, u_y, u_z, "
    "v_x, v_y, v_z, tan_half_fov, near, far, tan_cone, closest, projection, origin_x, origin_y, origin_z, u0, v0, "
    "d0, extent, depth_extent, depth_slices";
constexpr int kGridColumnCount = 31;

/// Table job_grids: a GridSpec's fields, each projection's own zero in the other's rows.
constexpr const char* kCreateJobGrids =
    "CREATE TABLE IF NOT EXISTS job_grids(job_id TEXT REFERENCES jobs(id), grid INTEGER, light INTEGER, "
    "log2_resolution INTEGER, position_x REAL, position_y REAL, position_z REAL, dir_x REAL, dir_y REAL, dir_z REAL, "
    "u_x REAL, u_y REAL, u_z REAL, v_x REAL, v_y REAL, v_z REAL, tan_half_fov REAL, near REAL, far REAL, "
    "tan_cone REAL, closest REAL, projection INTEGER NOT NULL DEFAULT 1, origin_x REAL NOT NULL DEFAULT 0, "
    "origin_y REAL NOT NULL DEFAULT 0, origin_z REAL NOT NULL DEFAULT 0, u0 REAL NOT NULL DEFAULT 0, "
    "v0 REAL NOT NULL DEFAULT 0, d0 REAL NOT NULL DEFAULT 0, extent REAL NOT NULL DEFAULT 0, "
    "depth_extent REAL NOT NULL DEFAULT 0, depth_slices INTEGER NOT NULL DEFAULT 0, PRIMARY KEY(job_id, grid))";

JobGrid readGrid(const Statement& s) {
  JobGrid j;
  GridSpec& g = j.grid;
  j.light = uint32_t(s.i64(2));
  g.log2Resolution = int(s.i64(3));
  g.position = readVec(s, 4);
  g.frame.dir = readVec(s, 7);
  g.frame.u = readVec(s, 10);
  g.frame.v = readVec(s, 13);
  g.tanHalfFov = s.f64(16);
  g.near = s.f64(17);
  g.far = s.f64(18);
  g.tanCone = s.f64(19);
  // SQLite keeps no infinity apart from NULL on every path: none is stored as NULL.
  j.closest = s.isNull(20) ? std::numeric_limits<double>::infinity() : s.f64(20);
  g.projection = s.i64(21) == int64_t(Projection::Orthographic) ? Projection::Orthographic : Projection::Perspective;
  g.origin = readVec(s, 22);
  g.u0 = s.f64(25);
  g.v0 = s.f64(26);
  g.d0 = s.f64(27);
  g.extent = s.f64(28);
  g.depthExtent = s.f64(29);
  g.depthSlices = uint32_t(s.i64(30));
  return j;
}

void bindGrid(Statement& s, const std::string& jobId, size_t index, const JobGrid& j) {
  const GridSpec& g = j.grid;
  s.text(1, jobId).bind(2, int64_t(index)).bind(3, int64_t(j.light)).bind(4, int64_t(g.log2Resolution));
  int c = 5;
  for (const Vec3* v : {&g.position, &g.frame.dir, &g.frame.u, &g.frame.v})
    for (double x : {v->x, v->y, v->z}) s.bind(c++, x);
  for (double x : {g.tanHalfFov, g.near, g.far, g.tanCone}) s.bind(c++, x);
  if (std::isfinite(j.closest)) s.bind(c, j.closest);
  ++c;
  s.bind(c++, int64_t(g.projection));
  for (double x : {g.origin.x, g.origin.y, g.origin.z, g.u0, g.v0, g.d0, g.extent, g.depthExtent}) s.bind(c++, x);
  s.bind(c++, int64_t(g.depthSlices));
}

}  // namespace

namespace {

/// The keys a query selects (one text column, bound to `beforeMs` and `limit`), then each
/// deleted by every statement of `deletes`: one pruning pass, inside the caller's transaction.
std::vector<std::string> selectAndDelete(sqlite3* db, const char* select, int64_t beforeMs, size_t limit,
                                         std::initializer_list<const char*> deletes) {
  std::vector<std::string> keys;
  {
    Statement s(db, select);
    s.bind(1, beforeMs).bind(2, int64_t(limit));
    while (s.step()) keys.push_back(s.str(0));
  }
  for (const char* sql : deletes) {
    Statement d(db, sql);
    for (const std::string& key : keys) {
      d.text(1, key);
      d.run();
      d.reset();
    }
  }
  return keys;
}

/// Now, in Unix milliseconds, by SQLite's clock (the system's): when a scene was last used.
constexpr const char* kNowMs = "CAST(strftime('%s', 'now') AS INTEGER) * 1000";

}  // namespace

FarmStore::FarmStore(const std::string& path, SpecRewrite rewrite) {
  if (sqlite3_open(path.c_str(), &db_) != SQLITE_OK) {
    std::string msg = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    throw std::runtime_error("cannot open the job store " + path + ": " + msg);
  }
  sqlite3_busy_timeout(db_, 5000);
  {
    // The durability argument rests on WAL (R25): a file system that refuses it is an error.
    Statement wal(db_, "PRAGMA journal_mode=WAL");
    if (!wal.step() || wal.str(0) != "wal")
      throw std::runtime_error("the job store " + path + " cannot use write-ahead logging on this file system");
  }
  {
    // A damaged store is refused at start, with what to do, rather than found out by the
    // first job that reads the damaged page (R25).
    std::string problems;
    try {
      Statement check(db_, "PRAGMA quick_check(5)");
      while (check.step())
        if (check.str(0) != "ok") problems += (problems.empty() ? "" : "; ") + check.str(0);
    } catch (const StoreUnavailable&) {
      throw;
    } catch (const std::runtime_error& e) {
      problems = e.what();
    }
    if (!problems.empty())
      throw std::runtime_error("the job store " + path + " is damaged (" + problems +
                               "): restore it from a backup, or start with an empty --data folder");
  }
  // FULL: an acknowledged tile or upload must survive a power cut, not only a crash.
  exec("PRAGMA synchronous=FULL");
  exec("PRAGMA foreign_keys=ON");
  // The schema is made or upgraded in one transaction with its version: a crash half-way
  // leaves the store as it was, never a version whose columns are half there.
  Transaction schema(db_);
  bool rewriteSpecs = false;
  exec(
      "CREATE TABLE IF NOT EXISTS scenes(hash TEXT PRIMARY KEY, file_name TEXT, total_size INTEGER, received INTEGER,"
      " complete INTEGER, triangles INTEGER, geometry_hash TEXT, last_used_ms INTEGER NOT NULL DEFAULT 0,"
      " owner TEXT NOT NULL DEFAULT '')");
  {
    Statement v(db_, "PRAGMA user_version");
    v.step();
    const int64_t version = v.i64(0);
    Statement t(db_, "SELECT COUNT(*) FROM sqlite_master WHERE type = 'table' AND name = 'jobs'");
    t.step();
    const bool existing = t.i64(0) > 0;
    const bool upgradable = existing && version >= 2 && version < kSchemaVersion;
    if (existing && version != kSchemaVersion && !upgradable)
      throw std::runtime_error("the job store " + path + " has schema version " + std::to_string(version == 0 ? 1 : version) +
                               "; this cpvs-server reads version " + std::to_string(kSchemaVersion) +
                               ": finish its jobs with the server that made it, or start with an empty --data folder");
    if (upgradable && version == 2) exec("ALTER TABLE jobs ADD COLUMN renderer INTEGER NOT NULL DEFAULT 0");
    if (upgradable && version <= 4) {
      exec("ALTER TABLE jobs ADD COLUMN receivers INTEGER NOT NULL DEFAULT 0");
      exec("ALTER TABLE jobs ADD COLUMN receiver_pcf INTEGER NOT NULL DEFAULT 9");
      exec("ALTER TABLE jobs ADD COLUMN receiver_hash TEXT NOT NULL DEFAULT ''");
      exec("ALTER TABLE jobs ADD COLUMN plan TEXT NOT NULL DEFAULT ''");
    }
    if (upgradable && version <= 5) exec("ALTER TABLE tiles ADD COLUMN failed_by TEXT");
    if (upgradable && version <= 6) {
      exec("ALTER TABLE scenes ADD COLUMN last_used_ms INTEGER NOT NULL DEFAULT 0");
      exec((std::string("UPDATE scenes SET last_used_ms = ") + kNowMs).c_str());  // their age is unknown
      exec("ALTER TABLE jobs ADD COLUMN owner TEXT NOT NULL DEFAULT ''");
      Statement tracks(db_, "SELECT COUNT(*) FROM sqlite_master WHERE type = 'table' AND name = 'tracks'");
      tracks.step();
      if (tracks.i64(0) > 0) exec("ALTER TABLE tracks ADD COLUMN owner TEXT NOT NULL DEFAULT ''");
    }
    if (upgradable && version <= 7) exec("ALTER TABLE jobs ADD COLUMN lights BLOB NOT NULL DEFAULT ''");
    if (upgradable && version <= 9) exec("ALTER TABLE scenes ADD COLUMN owner TEXT NOT NULL DEFAULT ''");
    if (upgradable && version <= 10) {
      exec("ALTER TABLE jobs ADD COLUMN receiver_scene TEXT NOT NULL DEFAULT ''");
      Statement tracks(db_, "SELECT COUNT(*) FROM sqlite_master WHERE type = 'table' AND name = 'tracks'");
      tracks.step();
      if (tracks.i64(0) > 0) {
        exec("ALTER TABLE tracks ADD COLUMN scene_hash TEXT NOT NULL DEFAULT ''");
        exec("ALTER TABLE tracks ADD COLUMN receiver_scene TEXT NOT NULL DEFAULT ''");
      }
      rewriteSpecs = true;
    }
    if (upgradable && version <= 11) {
      exec("ALTER TABLE tiles ADD COLUMN work INTEGER NOT NULL DEFAULT 0");
      exec("ALTER TABLE tiles ADD COLUMN seconds REAL NOT NULL DEFAULT 0");
    }
    if (upgradable && version <= 12) exec("ALTER TABLE tiles ADD COLUMN reused INTEGER NOT NULL DEFAULT 0");
    // Older stores' grids are all cubic. (Before 8 the table is made below, with the column.)
    if (upgradable && version >= 8) exec("ALTER TABLE job_grids ADD COLUMN depth_slices INTEGER NOT NULL DEFAULT 0");
    if (upgradable && version <= 8) {
      // A sun job's grid moves from the jobs table's columns to its job_grids row.
      if (version == 8) {
        exec("ALTER TABLE job_grids ADD COLUMN projection INTEGER NOT NULL DEFAULT 1");
        for (const char* column : {"origin_x", "origin_y", "origin_z", "u0", "v0", "d0", "extent", "depth_extent"})
          exec((std::string("ALTER TABLE job_grids ADD COLUMN ") + column + " REAL NOT NULL DEFAULT 0").c_str());
      } else {
        exec(kCreateJobGrids);
      }
      exec(
          (std::string("INSERT INTO job_grids(") + kGridColumns + ") "
          "SELECT id, 0, 0, log2_resolution, 0, 0, 0, light_dir_x, light_dir_y, light_dir_z, frame_u_x, frame_u_y, "
          "frame_u_z, frame_v_x, frame_v_y, frame_v_z, 0, 0, 0, 0, NULL, 0, origin_x, origin_y, origin_z, u0, v0, d0, "
          "extent, depth_extent, 0 FROM jobs WHERE length(lights) = 0").c_str());
      for (const char* column : {"light_dir_x", "light_dir_y", "light_dir_z", "frame_u_x", "frame_u_y", "frame_u_z",
                                 "frame_v_x", "frame_v_y", "frame_v_z", "origin_x", "origin_y", "origin_z", "u0", "v0",
                                 "d0", "extent", "depth_extent", "log2_resolution"})
        exec((std::string("ALTER TABLE jobs DROP COLUMN ") + column).c_str());
    }
  }
  exec(
      "CREATE TABLE IF NOT EXISTS jobs(id TEXT PRIMARY KEY, request_id TEXT UNIQUE, scene_hash TEXT, geometry_hash "
      "TEXT, spec TEXT, state INTEGER, priority INTEGER, created_ms INTEGER, started_ms INTEGER, finished_ms INTEGER, "
      "error TEXT, artifact_checksum TEXT, tiles_total INTEGER, bytes INTEGER, file_bytes INTEGER, "
      "peak_merge_bytes INTEGER, closed INTEGER, exit_mode INTEGER, cull "
      "INTEGER, compress INTEGER, undefined_rule INTEGER, log2_tile_size INTEGER, hash_kind INTEGER, renderer INTEGER, "
      "receivers INTEGER, receiver_pcf INTEGER, receiver_hash TEXT, plan TEXT, owner TEXT NOT NULL DEFAULT '', "
      "lights TEXT NOT NULL DEFAULT '', receiver_scene TEXT NOT NULL DEFAULT '')");
  exec(kCreateJobGrids);
  exec(
      "CREATE TABLE IF NOT EXISTS tiles(job_id TEXT REFERENCES jobs(id), idx INTEGER, state INTEGER, attempts "
      "INTEGER, lease_id TEXT, deadline_ms INTEGER, last_error TEXT, failed_by TEXT, work INTEGER NOT NULL DEFAULT 0, "
      "seconds REAL NOT NULL DEFAULT 0, reused INTEGER NOT NULL DEFAULT 0, PRIMARY KEY(job_id, idx))");
  exec("CREATE INDEX IF NOT EXISTS tiles_by_state ON tiles(state, job_id)");
  // A job's next queued tile in tile order, without walking the tiles done before it.
  exec("CREATE INDEX IF NOT EXISTS tiles_by_job_state ON tiles(job_id, state, idx)");
  exec("CREATE INDEX IF NOT EXISTS jobs_by_created ON jobs(created_ms, id)");
  exec("CREATE INDEX IF NOT EXISTS jobs_by_finished ON jobs(state, finished_ms)");
  exec(
      "CREATE TABLE IF NOT EXISTS leases(lease_id TEXT PRIMARY KEY, job_id TEXT, idx INTEGER, worker_id TEXT, "
      "granted_ms INTEGER)");
  exec("CREATE TABLE IF NOT EXISTS job_stages(job_id TEXT, stage TEXT, seconds REAL, PRIMARY KEY(job_id, stage))");
  exec(
      "CREATE TABLE IF NOT EXISTS tracks(id TEXT PRIMARY KEY, request_id TEXT UNIQUE, spec TEXT, state INTEGER, "
      "created_ms INTEGER, error TEXT, keyframes_total INTEGER, next_keyframe INTEGER, published INTEGER, "
      "skipped INTEGER, latest_sequence INTEGER, owner TEXT NOT NULL DEFAULT '', scene_hash TEXT NOT NULL DEFAULT '', "
      "receiver_scene TEXT NOT NULL DEFAULT '')");
  exec(
      "CREATE TABLE IF NOT EXISTS keyframes(track_id TEXT REFERENCES tracks(id), keyframe INTEGER, instant_ms "
      "INTEGER, dir_x REAL, dir_y REAL, dir_z REAL, job_id TEXT, state INTEGER, PRIMARY KEY(track_id, keyframe))");
  exec(
      "CREATE TABLE IF NOT EXISTS versions(track_id TEXT REFERENCES tracks(id), sequence INTEGER, keyframe INTEGER, "
      "instant_ms INTEGER, dir_x REAL, dir_y REAL, dir_z REAL, job_id TEXT, checksum TEXT, file_bytes INTEGER, "
      "published_ms INTEGER, PRIMARY KEY(track_id, sequence))");
  if (rewriteSpecs) {
    // In the schema's transaction: a crash leaves the old version with its old specs.
    if (rewrite.job) {
      std::vector<JobRecord> jobs;
      for (Statement s(db_, "SELECT id, spec, lights FROM jobs"); s.step();) {
        JobRecord& j = jobs.emplace_back();
        j.id = s.str(0), j.spec = s.str(1), j.lights = s.str(2);
      }
      for (JobRecord& j : jobs) {
        rewrite.job(j);
        Statement u(db_, "UPDATE jobs SET spec = ?, lights = ?, receiver_scene = ? WHERE id = ?");
        u.text(1, j.spec).text(2, j.lights).text(3, j.receiverScene).text(4, j.id);
        u.run();
      }
    }
    if (rewrite.track) {
      std::vector<TrackRecord> tracks;
      for (Statement s(db_, "SELECT id, spec FROM tracks"); s.step();) {
        TrackRecord& t = tracks.emplace_back();
        t.id = s.str(0), t.spec = s.str(1);
      }
      for (TrackRecord& t : tracks) {
        rewrite.track(t);
        Statement u(db_, "UPDATE tracks SET spec = ?, scene_hash = ?, receiver_scene = ? WHERE id = ?");
        u.text(1, t.spec).text(2, t.sceneHash).text(3, t.receiverScene).text(4, t.id);
        u.run();
      }
    }
  }
  exec(("PRAGMA user_version = " + std::to_string(kSchemaVersion)).c_str());
  schema.commit();
}

FarmStore::~FarmStore() { sqlite3_close(db_); }

void FarmStore::exec(const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    std::string msg = err ? err : "unknown error";
    sqlite3_free(err);
    throw std::runtime_error("sqlite: " + msg + " in: " + sql);
  }
}

std::optional<SceneRecord> FarmStore::scene(const std::string& hash) {
  std::lock_guard lock(mutex_);
  Statement s(db_,
              "SELECT hash, file_name, total_size, received, complete, triangles, geometry_hash, owner FROM scenes "
              "WHERE hash = ?");
  s.text(1, hash);
  if (!s.step()) return std::nullopt;
  SceneRecord r;
  r.hash = s.str(0);
  r.fileName = s.str(1);
  r.totalSize = uint64_t(s.i64(2));
  r.received = uint64_t(s.i64(3));
  r.complete = s.i64(4) != 0;
  r.triangles = uint64_t(s.i64(5));
  r.geometryHash = s.str(6);
  r.owner = s.str(7);
  return r;
}

void FarmStore::putScene(const SceneRecord& r) {
  std::lock_guard lock(mutex_);
  Statement s(db_, (std::string("INSERT OR REPLACE INTO scenes(hash, file_name, total_size, received, complete, "
                                 "triangles, geometry_hash, owner, last_used_ms) VALUES(?, ?, ?, ?, ?, ?, ?, ?, ") +
                     kNowMs + ")")
                        .c_str());
  s.text(1, r.hash).text(2, r.fileName).bind(3, int64_t(r.totalSize)).bind(4, int64_t(r.received));
  s.bind(5, int64_t(r.complete)).bind(6, int64_t(r.triangles)).text(7, r.geometryHash).text(8, r.owner);
  s.run();
}

SceneBytes FarmStore::sceneBytesOf(const std::string& owner) {
  std::lock_guard lock(mutex_);
  Statement s(db_,
              "SELECT COALESCE(SUM(CASE WHEN complete = 0 THEN total_size END), 0), "
              "COALESCE(SUM(CASE WHEN complete = 1 THEN total_size END), 0) FROM scenes WHERE owner = ?");
  s.text(1, owner);
  s.step();
  return {uint64_t(s.i64(0)), uint64_t(s.i64(1))};
}

void FarmStore::touchScene(const std::string& hash) {
  std::lock_guard lock(mutex_);
  Statement s(db_, (std::string("UPDATE scenes SET last_used_ms = ") + kNowMs + " WHERE hash = ?").c_str());
  s.text(1, hash);
  s.run();
}

std::vector<std::string> FarmStore::pruneUnusedScenes(int64_t beforeMs, size_t limit) {
  std::lock_guard lock(mutex_);
  Transaction t(db_);
  // A receiver volume is a scene too: a scene any job names, as its scene or its
  // receivers', or an active track bakes, is kept.
  std::vector<std::string> hashes = selectAndDelete(
      db_,
      "SELECT hash FROM scenes WHERE complete = 1 AND last_used_ms < ? "
      "AND hash NOT IN (SELECT scene_hash FROM jobs) "
      "AND hash NOT IN (SELECT receiver_scene FROM jobs) "
      "AND hash NOT IN (SELECT scene_hash FROM tracks WHERE state = 1) "
      "AND hash NOT IN (SELECT receiver_scene FROM tracks WHERE state = 1) "
      "ORDER BY last_used_ms LIMIT ?",
      beforeMs, limit, {"DELETE FROM scenes WHERE hash = ?"});
  t.commit();
  return hashes;
}

bool FarmStore::responsive(int timeoutMs) {
  std::unique_lock lock(mutex_, std::defer_lock);
  if (!lock.try_lock_for(std::chrono::milliseconds(timeoutMs))) return false;
  sqlite3_busy_timeout(db_, timeoutMs);
  const bool free = sqlite3_exec(db_, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr) == SQLITE_OK;
  if (free) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
  sqlite3_busy_timeout(db_, 5000);
  return free;
}

std::vector<std::string> FarmStore::incompleteScenes() {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT hash FROM scenes WHERE complete = 0");
  std::vector<std::string> out;
  while (s.step()) out.push_back(s.str(0));
  return out;
}

void FarmStore::deleteScene(const std::string& hash) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "DELETE FROM scenes WHERE hash = ? AND complete = 0");
  s.text(1, hash);
  s.run();
}

std::optional<JobRecord> FarmStore::job(const std::string& id, bool withCounts) {
  std::lock_guard lock(mutex_);
  Statement s(db_, (std::string("SELECT ") + kJobColumns + " FROM jobs WHERE id = ?").c_str());
  s.text(1, id);
  if (!s.step()) return std::nullopt;
  JobRecord j = readJob(s);
  fillJobCounts(j, withCounts);
  return j;
}

uint64_t FarmStore::outstandingTiles(const std::string& jobId) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT COUNT(*) FROM tiles WHERE state IN (0, 1) AND job_id = ?");
  s.text(1, jobId);
  s.step();
  return uint64_t(s.i64(0));
}

void FarmStore::fillJobCounts(JobRecord& j, bool withCounts) {
  Statement g(db_, (std::string("SELECT ") + kGridColumns + " FROM job_grids WHERE job_id = ? ORDER BY grid").c_str());
  g.text(1, j.id);
  while (g.step()) j.grids.push_back(readGrid(g));
  if (!withCounts) return;
  Statement d(db_, "SELECT COUNT(*), COALESCE(SUM(state = 4), 0), COALESCE(SUM(state = 5), 0), "
                   "COALESCE(SUM(state = 2 AND reused = 1), 0) FROM tiles WHERE job_id = ? AND state IN (2, 4, 5)");
  d.text(1, j.id);
  d.step();
  j.tilesDone = uint64_t(d.i64(0));
  j.tilesUntouched = uint64_t(d.i64(1));
  j.tilesUnread = uint64_t(d.i64(2));
  j.tilesReused = uint64_t(d.i64(3));
  Statement st(db_, "SELECT stage, seconds FROM job_stages WHERE job_id = ?");
  st.text(1, j.id);
  while (st.step()) j.stages[st.str(0)] = st.f64(1);
}

std::optional<JobRecord> FarmStore::jobByRequest(const std::string& requestId) {
  std::string id;
  {
    std::lock_guard lock(mutex_);
    Statement s(db_, "SELECT id FROM jobs WHERE request_id = ?");
    s.text(1, requestId);
    if (!s.step()) return std::nullopt;
    id = s.str(0);
  }
  return job(id);
}

void FarmStore::createJob(const JobRecord& j, const std::vector<TileState>& states, const std::vector<uint32_t>& work) {
  CPVS_CHECK(states.empty() || states.size() == j.tilesTotal);
  CPVS_CHECK(work.empty() || work.size() == j.tilesTotal);
  std::lock_guard lock(mutex_);
  Transaction t(db_);
  Statement s(db_, (std::string("INSERT INTO jobs(") + kJobColumns + ") VALUES(" + parameterMarks(kJobColumnCount) + ")").c_str());
  bindJob(s, j);
  s.run();
  Statement tile(db_,
                 "INSERT INTO tiles(job_id, idx, state, attempts, lease_id, deadline_ms, last_error, failed_by, work) "
                 "VALUES(?, ?, ?, 0, NULL, 0, '', NULL, ?)");  // prepared once
  for (uint64_t i = 0; i < j.tilesTotal; ++i) {
    const TileState state = states.empty() ? TileState::Queued : states[i];
    tile.text(1, j.id).bind(2, int64_t(i)).bind(3, int64_t(state)).bind(4, int64_t(work.empty() ? 0 : work[i]));
    tile.run();
    tile.reset();
  }
  Statement grid(db_, (std::string("INSERT INTO job_grids(") + kGridColumns + ") VALUES(" + parameterMarks(kGridColumnCount) +
                       ")").c_str());
  for (size_t k = 0; k < j.grids.size(); ++k) {
    bindGrid(grid, j.id, k, j.grids[k]);
    grid.run();
    grid.reset();
  }
  t.commit();
}

std::vector<JobRecord> FarmStore::jobs(bool includeFinished) {
  return jobsAfter(includeFinished, std::numeric_limits<int64_t>::min(), "", kNoLimit);
}

std::vector<JobRecord> FarmStore::jobsAfter(bool includeFinished, int64_t createdMs, const std::string& id,
                                            size_t limit, const std::optional<std::string>& owner) {
  std::lock_guard lock(mutex_);
  Statement s(db_, (std::string("SELECT ") + kJobColumns +
                    " FROM jobs WHERE (created_ms > ?1 OR (created_ms = ?1 AND id > ?2))" +
                    (includeFinished ? "" : " AND state IN (1, 2, 3)") +
                    (owner ? " AND owner IN (?4, '')" : "") + " ORDER BY created_ms, id LIMIT ?3")
                       .c_str());
  s.bind(1, createdMs).text(2, id).bind(3, limit == kNoLimit ? int64_t(-1) : int64_t(limit));  // -1: no limit
  if (owner) s.text(4, *owner);
  std::vector<JobRecord> out;
  while (s.step()) out.push_back(readJob(s));
  for (JobRecord& j : out) fillJobCounts(j);
  return out;
}

std::vector<std::string> FarmStore::pruneFinishedJobs(int64_t beforeMs, size_t limit) {
  std::lock_guard lock(mutex_);
  Transaction t(db_);
  std::vector<std::string> ids = selectAndDelete(
      db_,
      "SELECT id FROM jobs WHERE state IN (4, 5, 6) AND finished_ms < ? "
      "AND id NOT IN (SELECT job_id FROM versions) "
      "AND id NOT IN (SELECT k.job_id FROM keyframes k JOIN tracks t ON t.id = k.track_id "
      "WHERE k.state = 0 AND t.state = 1 AND k.job_id IS NOT NULL) "
      "ORDER BY finished_ms, id LIMIT ?",
      beforeMs, limit,
      {"DELETE FROM leases WHERE job_id = ?", "DELETE FROM tiles WHERE job_id = ?", "DELETE FROM job_grids WHERE job_id = ?",
       "DELETE FROM job_stages WHERE job_id = ?", "DELETE FROM jobs WHERE id = ?"});
  t.commit();
  return ids;
}

FarmStore::Census FarmStore::census() {
  std::lock_guard lock(mutex_);
  Census c;
  Statement j(db_, "SELECT state, COUNT(*), COALESCE(SUM(file_bytes), 0) FROM jobs GROUP BY state");
  while (j.step()) {
    const auto state = JobState(j.i64(0));
    c.jobs[state] = uint64_t(j.i64(1));
    if (state == JobState::Done) c.artifactBytes = uint64_t(j.i64(2));
  }
  Statement t(db_, "SELECT state, COUNT(*) FROM tiles WHERE state IN (0, 1) AND job_id IN "
                   "(SELECT id FROM jobs WHERE state IN (1, 2, 3)) GROUP BY state");
  while (t.step()) (t.i64(0) == int64_t(TileState::Queued) ? c.tilesQueued : c.tilesLeased) = uint64_t(t.i64(1));
  return c;
}

size_t FarmStore::activeJobCount() {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT COUNT(*) FROM jobs WHERE state IN (1, 2, 3)");
  s.step();
  return size_t(s.i64(0));
}

size_t FarmStore::activeJobCount(const std::string& owner) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT COUNT(*) FROM jobs WHERE state IN (1, 2, 3) AND owner = ?");
  s.text(1, owner);
  s.step();
  return size_t(s.i64(0));
}

void FarmStore::setJobState(const std::string& id, JobState state, const std::string& error, int64_t nowMs) {
  std::lock_guard lock(mutex_);
  Statement s(db_,
              "UPDATE jobs SET state = ?, error = ?, started_ms = CASE WHEN ? = 2 AND started_ms = 0 THEN ? ELSE "
              "started_ms END, finished_ms = CASE WHEN ? IN (4, 5, 6) THEN ? ELSE finished_ms END WHERE id = ?");
  s.bind(1, int64_t(state)).text(2, error).bind(3, int64_t(state)).bind(4, nowMs).bind(5, int64_t(state));
  s.bind(6, nowMs).text(7, id);
  s.run();
}

bool FarmStore::finishJob(const std::string& id, uint64_t bytes, uint64_t fileBytes, uint64_t peak,
                          const std::string& checksum, int64_t nowMs) {
  std::lock_guard lock(mutex_);
  Statement s(db_,
              "UPDATE jobs SET state = 4, bytes = ?, file_bytes = ?, peak_merge_bytes = MAX(peak_merge_bytes, ?), "
              "artifact_checksum = ?, finished_ms = ? WHERE id = ? AND state IN (1, 2, 3)");
  s.bind(1, int64_t(bytes)).bind(2, int64_t(fileBytes)).bind(3, int64_t(peak)).text(4, checksum).bind(5, nowMs);
  s.text(6, id);
  s.run();
  return sqlite3_changes(db_) > 0;
}

void FarmStore::addStageSeconds(const std::string& id, const std::map<std::string, double>& stages) {
  std::lock_guard lock(mutex_);
  Transaction t(db_);
  for (const auto& [stage, seconds] : stages) {
    Statement s(db_,
                "INSERT INTO job_stages VALUES(?, ?, ?) ON CONFLICT(job_id, stage) DO UPDATE SET seconds = seconds + "
                "excluded.seconds");
    s.text(1, id).text(2, stage).bind(3, seconds);
    s.run();
  }
  t.commit();
}

void FarmStore::setPeakMergeBytes(const std::string& id, uint64_t bytes) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "UPDATE jobs SET peak_merge_bytes = MAX(peak_merge_bytes, ?) WHERE id = ?");
  s.bind(1, int64_t(bytes)).text(2, id);
  s.run();
}

std::optional<LeaseRecord> FarmStore::leaseNextTile(const std::string& workerId, const std::string& leaseId,
                                                    int64_t nowMs, int64_t deadlineMs) {
  std::lock_guard lock(mutex_);
  Transaction t(db_);
  // The job first, from the few unfinished ones (never a sort of every queued tile: R2):
  // its priority, whether it has a tile this worker did not fail last, its tiles out on
  // lease (counted once per job from the state index), its age. Then its first such tile.
  Statement pickJob(db_,
                    "WITH leased AS (SELECT job_id, COUNT(*) AS n FROM tiles WHERE state = 1 GROUP BY job_id) "
                    "SELECT j.id, NOT EXISTS (SELECT 1 FROM tiles t WHERE t.job_id = j.id AND t.state = 0 "
                    "AND t.failed_by IS NOT ?1) AS onlyFailed FROM jobs j LEFT JOIN leased l ON l.job_id = j.id "
                    "WHERE j.state IN (1, 2) AND EXISTS (SELECT 1 FROM tiles t WHERE t.job_id = j.id AND t.state = 0) "
                    "ORDER BY j.priority DESC, onlyFailed, COALESCE(l.n, 0), j.created_ms, j.id LIMIT 1");
  pickJob.text(1, workerId);
  if (!pickJob.step()) return std::nullopt;
  const std::string jobId = pickJob.str(0);
  const bool onlyFailed = pickJob.i64(1) != 0;
  Statement pickTile(db_, onlyFailed ? "SELECT idx FROM tiles WHERE job_id = ?1 AND state = 0 ORDER BY idx LIMIT 1"
                                     : "SELECT idx FROM tiles WHERE job_id = ?1 AND state = 0 AND failed_by IS NOT ?2 "
                                       "ORDER BY idx LIMIT 1");
  pickTile.text(1, jobId);
  if (!onlyFailed) pickTile.text(2, workerId);
  if (!pickTile.step()) return std::nullopt;
  LeaseRecord r{leaseId, jobId, workerId, uint64_t(pickTile.i64(0)), deadlineMs, nowMs};
  Statement upd(db_, "UPDATE tiles SET state = 1, attempts = attempts + 1, lease_id = ?, deadline_ms = ? "
                     "WHERE job_id = ? AND idx = ?");
  upd.text(1, leaseId).bind(2, deadlineMs).text(3, r.jobId).bind(4, int64_t(r.tile));
  upd.run();
  Statement ins(db_, "INSERT INTO leases VALUES(?, ?, ?, ?, ?)");
  ins.text(1, leaseId).text(2, r.jobId).bind(3, int64_t(r.tile)).text(4, workerId).bind(5, nowMs);
  ins.run();
  Statement start(db_, "UPDATE jobs SET state = 2, started_ms = ? WHERE id = ? AND state = 1");
  start.bind(1, nowMs).text(2, r.jobId);
  start.run();
  t.commit();
  return r;
}

std::optional<LeaseRecord> FarmStore::lease(const std::string& leaseId) {
  std::lock_guard lock(mutex_);
  Statement s(db_,
              "SELECT l.lease_id, l.job_id, l.worker_id, l.idx, COALESCE(t.deadline_ms, 0), l.granted_ms FROM leases l "
              "LEFT JOIN tiles t ON t.job_id = l.job_id AND t.idx = l.idx AND t.lease_id = l.lease_id WHERE "
              "l.lease_id = ?");
  s.text(1, leaseId);
  if (!s.step()) return std::nullopt;
  return LeaseRecord{s.str(0), s.str(1), s.str(2), uint64_t(s.i64(3)), s.i64(4), s.i64(5)};
}

bool FarmStore::renewLease(const std::string& leaseId, int64_t deadlineMs) {
  std::lock_guard lock(mutex_);
  Statement s(db_,
              "UPDATE tiles SET deadline_ms = ? WHERE lease_id = ? AND state = 1 AND job_id IN (SELECT id FROM jobs "
              "WHERE state IN (1, 2))");
  s.bind(1, deadlineMs).text(2, leaseId);
  s.run();
  return sqlite3_changes(db_) > 0;
}

std::optional<TileState> FarmStore::tileState(const std::string& jobId, uint64_t tile) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT state FROM tiles WHERE job_id = ? AND idx = ?");
  s.text(1, jobId).bind(2, int64_t(tile));
  if (!s.step()) return std::nullopt;
  return TileState(s.i64(0));
}

bool FarmStore::completeTile(const std::string& jobId, uint64_t tile, double seconds, bool reused) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "UPDATE tiles SET state = 2, lease_id = NULL, seconds = ?, reused = ? WHERE job_id = ? AND idx = ? AND "
                   "state IN (0, 1)");
  s.bind(1, seconds).bind(2, int64_t(reused)).text(3, jobId).bind(4, int64_t(tile));
  s.run();
  return sqlite3_changes(db_) > 0;
}

TileCosts FarmStore::tileCosts(const std::string& jobId) {
  std::lock_guard lock(mutex_);
  // The job's done tiles with their seconds, then its queued and leased ones still to
  // do: two index ranges of (job, state).
  Statement s(db_,
              "SELECT COUNT(*), TOTAL(work), TOTAL(work * work), TOTAL(seconds), TOTAL(work * seconds) FROM tiles "
              "WHERE job_id = ? AND state = 2 AND work > 0 AND seconds > 0 AND reused = 0");
  s.text(1, jobId);
  TileCosts c;
  if (s.step()) c.done = {double(s.i64(0)), s.f64(1), s.f64(2), s.f64(3), s.f64(4)};
  Statement left(db_, "SELECT COUNT(*), TOTAL(work) FROM tiles WHERE job_id = ? AND state IN (0, 1) AND work > 0");
  left.text(1, jobId);
  if (left.step()) {
    c.leftTiles = uint64_t(left.i64(0));
    c.leftWork = left.f64(1);
  }
  return c;
}

std::optional<int> FarmStore::requeueTile(const std::string& leaseId, const std::string& error, bool counts) {
  std::lock_guard lock(mutex_);
  Transaction t(db_);
  Statement find(db_,
                 "SELECT t.job_id, t.idx, t.attempts, l.worker_id FROM tiles t JOIN leases l ON l.lease_id = t.lease_id "
                 "WHERE t.lease_id = ? AND t.state = 1");
  find.text(1, leaseId);
  if (!find.step()) return std::nullopt;
  const std::string jobId = find.str(0);
  const int64_t tile = find.i64(1);
  const int attempts = int(find.i64(2)) - (counts ? 0 : 1);
  Statement s(db_, "UPDATE tiles SET state = 0, lease_id = NULL, last_error = ?, attempts = ?, failed_by = ? "
                   "WHERE job_id = ? AND idx = ?");
  s.text(1, error).bind(2, int64_t(attempts)).text(3, find.str(3)).text(4, jobId).bind(5, tile);
  s.run();
  t.commit();
  return attempts;
}

void FarmStore::extendLeasesTo(int64_t deadlineMs) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "UPDATE tiles SET deadline_ms = MAX(deadline_ms, ?) WHERE state = 1");
  s.bind(1, deadlineMs);
  s.run();
}

void FarmStore::shiftLeaseDeadlines(int64_t deltaMs) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "UPDATE tiles SET deadline_ms = deadline_ms + ? WHERE state = 1");
  s.bind(1, deltaMs);
  s.run();
}

void FarmStore::requeueDoneTile(const std::string& jobId, uint64_t tile, const std::string& error) {
  std::lock_guard lock(mutex_);
  Transaction t(db_);
  Statement s(db_, "UPDATE tiles SET state = 0, lease_id = NULL, last_error = ? WHERE job_id = ? AND idx = ? AND "
                   "state = 2");
  s.text(1, error).text(2, jobId).bind(3, int64_t(tile));
  s.run();
  Statement j(db_, "UPDATE jobs SET state = 2 WHERE id = ? AND state = 3");
  j.text(1, jobId);
  j.run();
  t.commit();
}

std::vector<std::tuple<std::string, uint64_t, int>> FarmStore::expireLeases(int64_t nowMs) {
  std::lock_guard lock(mutex_);
  Transaction t(db_);
  std::vector<std::tuple<std::string, uint64_t, int>> out;
  Statement s(db_, "SELECT job_id, idx, attempts FROM tiles WHERE state = 1 AND deadline_ms < ?");
  s.bind(1, nowMs);
  while (s.step()) out.emplace_back(s.str(0), uint64_t(s.i64(1)), int(s.i64(2)));
  Statement u(db_, "UPDATE tiles SET state = 0, lease_id = NULL, last_error = 'lease expired' WHERE state = 1 AND "
                   "deadline_ms < ?");
  u.bind(1, nowMs);
  u.run();
  t.commit();
  return out;
}

std::vector<uint64_t> FarmStore::doneTiles(const std::string& jobId) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT idx FROM tiles WHERE job_id = ? AND state IN (2, 4, 5) ORDER BY idx");
  s.text(1, jobId);
  std::vector<uint64_t> out;
  while (s.step()) out.push_back(uint64_t(s.i64(0)));
  return out;
}

int FarmStore::tileAttempts(const std::string& jobId, uint64_t tile) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT attempts FROM tiles WHERE job_id = ? AND idx = ?");
  s.text(1, jobId).bind(2, int64_t(tile));
  return s.step() ? int(s.i64(0)) : 0;
}

void FarmStore::cancelTiles(const std::string& jobId) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "UPDATE tiles SET state = 3, lease_id = NULL WHERE job_id = ? AND state IN (0, 1)");
  s.text(1, jobId);
  s.run();
}

// --- Sun tracks -------------------------------------------------------------------------

namespace {

constexpr const char* kTrackColumns =
    "id, request_id, spec, state, created_ms, error, keyframes_total, next_keyframe, published, skipped, latest_sequence, "
    "owner, scene_hash, receiver_scene";

TrackRecord readTrack(Statement& s) {
  TrackRecord t;
  t.id = s.str(0);
  t.requestId = s.str(1);
  t.spec = s.str(2);
  t.state = int(s.i64(3));
  t.createdMs = s.i64(4);
  t.error = s.str(5);
  t.keyframesTotal = uint64_t(s.i64(6));
  t.nextKeyframe = uint64_t(s.i64(7));
  t.published = uint64_t(s.i64(8));
  t.skipped = uint64_t(s.i64(9));
  t.latestSequence = uint64_t(s.i64(10));
  t.owner = s.str(11);
  t.sceneHash = s.str(12);
  t.receiverScene = s.str(13);
  return t;
}

constexpr const char* kVersionColumns =
    "track_id, sequence, keyframe, instant_ms, dir_x, dir_y, dir_z, job_id, checksum, file_bytes, published_ms";

VersionRecord readVersion(Statement& s) {
  VersionRecord v;
  v.trackId = s.str(0);
  v.sequence = uint64_t(s.i64(1));
  v.keyframe = uint64_t(s.i64(2));
  v.instantMs = s.i64(3);
  v.direction = {s.f64(4), s.f64(5), s.f64(6)};
  v.jobId = s.str(7);
  v.checksum = s.str(8);
  v.fileBytes = uint64_t(s.i64(9));
  v.publishedMs = s.i64(10);
  return v;
}

}  // namespace

void FarmStore::createTrack(const TrackRecord& t) {
  std::lock_guard lock(mutex_);
  Statement s(db_, (std::string("INSERT INTO tracks(") + kTrackColumns + ") VALUES(?,?,?,?,?,?,?,?,?,?,?,?,?,?)").c_str());
  s.text(1, t.id).text(2, t.requestId).text(3, t.spec).bind(4, int64_t(t.state)).bind(5, t.createdMs).text(6, t.error);
  s.bind(7, int64_t(t.keyframesTotal)).bind(8, int64_t(t.nextKeyframe)).bind(9, int64_t(t.published));
  s.bind(10, int64_t(t.skipped)).bind(11, int64_t(t.latestSequence)).text(12, t.owner).text(13, t.sceneHash).text(14, t.receiverScene);
  s.run();
}

std::optional<TrackRecord> FarmStore::track(const std::string& id) {
  std::lock_guard lock(mutex_);
  Statement s(db_, (std::string("SELECT ") + kTrackColumns + " FROM tracks WHERE id = ?").c_str());
  s.text(1, id);
  if (!s.step()) return std::nullopt;
  return readTrack(s);
}

std::optional<TrackRecord> FarmStore::trackByRequest(const std::string& requestId) {
  std::lock_guard lock(mutex_);
  Statement s(db_, (std::string("SELECT ") + kTrackColumns + " FROM tracks WHERE request_id = ?").c_str());
  s.text(1, requestId);
  if (!s.step()) return std::nullopt;
  return readTrack(s);
}

std::vector<TrackRecord> FarmStore::tracks(bool includeEnded) {
  std::lock_guard lock(mutex_);
  Statement s(db_, (std::string("SELECT ") + kTrackColumns + " FROM tracks" + (includeEnded ? "" : " WHERE state = 1") +
                    " ORDER BY created_ms, id")
                       .c_str());
  std::vector<TrackRecord> out;
  while (s.step()) out.push_back(readTrack(s));
  return out;
}

void FarmStore::setTrackState(const std::string& id, int state, const std::string& error) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "UPDATE tracks SET state = ?, error = ? WHERE id = ?");
  s.bind(1, int64_t(state)).text(2, error).text(3, id);
  s.run();
}

void FarmStore::addKeyframe(const KeyframeRecord& k) {
  std::lock_guard lock(mutex_);
  Transaction tx(db_);
  Statement s(db_,
              "INSERT INTO keyframes(track_id, keyframe, instant_ms, dir_x, dir_y, dir_z, job_id, state) "
              "VALUES(?,?,?,?,?,?,?,0)");
  s.text(1, k.trackId).bind(2, int64_t(k.keyframe)).bind(3, k.instantMs).bind(4, k.direction.x);
  s.bind(5, k.direction.y).bind(6, k.direction.z).text(7, k.jobId);
  s.run();
  Statement u(db_, "UPDATE tracks SET next_keyframe = ? WHERE id = ? AND next_keyframe <= ?");
  u.bind(1, int64_t(k.keyframe + 1)).text(2, k.trackId).bind(3, int64_t(k.keyframe));
  u.run();
  tx.commit();
}

void FarmStore::advanceNextKeyframe(const std::string& trackId, uint64_t next) {
  std::lock_guard lock(mutex_);
  Statement u(db_, "UPDATE tracks SET next_keyframe = ? WHERE id = ? AND next_keyframe < ?");
  u.bind(1, int64_t(next)).text(2, trackId).bind(3, int64_t(next));
  u.run();
}

std::vector<KeyframeRecord> FarmStore::pendingKeyframes(const std::string& trackId) {
  std::lock_guard lock(mutex_);
  Statement s(db_,
              "SELECT keyframe, instant_ms, dir_x, dir_y, dir_z, job_id FROM keyframes WHERE track_id = ? AND state = 0 "
              "ORDER BY keyframe");
  s.text(1, trackId);
  std::vector<KeyframeRecord> out;
  while (s.step()) {
    KeyframeRecord k;
    k.trackId = trackId;
    k.keyframe = uint64_t(s.i64(0));
    k.instantMs = s.i64(1);
    k.direction = {s.f64(2), s.f64(3), s.f64(4)};
    k.jobId = s.str(5);
    out.push_back(k);
  }
  return out;
}

void FarmStore::skipKeyframe(const std::string& trackId, uint64_t keyframe) {
  std::lock_guard lock(mutex_);
  Transaction tx(db_);
  Statement s(db_, "UPDATE keyframes SET state = 2 WHERE track_id = ? AND keyframe = ? AND state = 0");
  s.text(1, trackId).bind(2, int64_t(keyframe));
  s.run();
  if (sqlite3_changes(db_) > 0) {
    Statement u(db_, "UPDATE tracks SET skipped = skipped + 1 WHERE id = ?");
    u.text(1, trackId);
    u.run();
  }
  tx.commit();
}

VersionRecord FarmStore::publishKeyframe(const std::string& trackId, uint64_t keyframe, const std::string& checksum,
                                         uint64_t fileBytes, uint64_t keep, int64_t nowMs) {
  std::lock_guard lock(mutex_);
  Transaction tx(db_);
  Statement k(db_,
              "SELECT instant_ms, dir_x, dir_y, dir_z, job_id FROM keyframes WHERE track_id = ? AND keyframe = ? AND "
              "state = 0");
  k.text(1, trackId).bind(2, int64_t(keyframe));
  if (!k.step()) throw std::runtime_error("keyframe " + std::to_string(keyframe) + " of track " + trackId + " is not pending");
  VersionRecord v;
  v.trackId = trackId;
  v.keyframe = keyframe;
  v.instantMs = k.i64(0);
  v.direction = {k.f64(1), k.f64(2), k.f64(3)};
  v.jobId = k.str(4);
  v.checksum = checksum;
  v.fileBytes = fileBytes;
  v.publishedMs = nowMs;
  Statement seq(db_, "SELECT latest_sequence FROM tracks WHERE id = ?");
  seq.text(1, trackId);
  seq.step();
  v.sequence = uint64_t(seq.i64(0)) + 1;
  Statement ins(db_, (std::string("INSERT INTO versions(") + kVersionColumns + ") VALUES(?,?,?,?,?,?,?,?,?,?,?)").c_str());
  ins.text(1, trackId).bind(2, int64_t(v.sequence)).bind(3, int64_t(keyframe)).bind(4, v.instantMs);
  ins.bind(5, v.direction.x).bind(6, v.direction.y).bind(7, v.direction.z).text(8, v.jobId).text(9, checksum);
  ins.bind(10, int64_t(fileBytes)).bind(11, nowMs);
  ins.run();
  Statement mark(db_, "UPDATE keyframes SET state = 1 WHERE track_id = ? AND keyframe = ?");
  mark.text(1, trackId).bind(2, int64_t(keyframe));
  mark.run();
  Statement t(db_, "UPDATE tracks SET latest_sequence = ?, published = published + 1 WHERE id = ?");
  t.bind(1, int64_t(v.sequence)).text(2, trackId);
  t.run();
  Statement prune(db_, "DELETE FROM versions WHERE track_id = ? AND sequence <= ?");
  prune.text(1, trackId).bind(2, int64_t(v.sequence) - int64_t(keep));
  prune.run();
  tx.commit();
  return v;
}

std::optional<VersionRecord> FarmStore::versionAfter(const std::string& trackId, uint64_t sequence) {
  std::lock_guard lock(mutex_);
  Statement s(db_, (std::string("SELECT ") + kVersionColumns +
                    " FROM versions WHERE track_id = ? AND sequence > ? ORDER BY sequence LIMIT 1")
                       .c_str());
  s.text(1, trackId).bind(2, int64_t(sequence));
  if (!s.step()) return std::nullopt;
  return readVersion(s);
}

bool FarmStore::jobWantedByAnotherTrack(const std::string& jobId, const std::string& trackId) {
  std::lock_guard lock(mutex_);
  Statement s(db_,
              "SELECT COUNT(*) FROM keyframes k JOIN tracks t ON t.id = k.track_id WHERE k.job_id = ? AND k.state = 0 "
              "AND t.state = 1 AND t.id != ?");
  s.text(1, jobId).text(2, trackId);
  s.step();
  return s.i64(0) > 0;
}

}  // namespace cpvs::server
