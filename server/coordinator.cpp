#include "coordinator.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "cpvs/bake/tile_plan.h"
#include "cpvs/base/error.h"
#include "cpvs/scene/import.h"
#include "cpvs/base/parse.h"
#include "cpvs/base/progress.h"
#include "cpvs/dag/merge.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/scene/source.h"
#include "cpvs/io/sub_dag_file.h"
#include "cpvs/net/convert.h"

namespace cpvs::server {

namespace fs = std::filesystem;

namespace {

int64_t nowMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::string randomId(const char* prefix) {
  static std::mutex m;
  static std::mt19937_64 rng{std::random_device{}()};
  std::lock_guard lock(m);
  char buf[40];
  std::snprintf(buf, sizeof buf, "%s%016llx", prefix, static_cast<unsigned long long>(rng()));
  return buf;
}

/// The extension of an uploaded file name, which tells the importer its format: a dot
/// and 1..10 letters or digits. FarmError otherwise.
std::string safeExtension(const std::string& fileName) {
  std::string ext = fs::path(fileName).extension().string();
  bool ok = ext.size() >= 2 && ext.size() <= 11;
  for (size_t i = 1; ok && i < ext.size(); ++i) ok = std::isalnum(static_cast<unsigned char>(ext[i])) != 0;
  if (!ok) throw FarmError(ErrorKind::InvalidArgument, "file name '" + fileName + "' has no usable extension");
  return ext;
}

void checkHashText(const std::string& hash, const char* what) {
  try {
    parseHashHex(hash, what);
  } catch (const InputError& e) {
    throw FarmError(ErrorKind::InvalidArgument, e.what());
  }
}

}  // namespace

Coordinator::Coordinator(CoordinatorConfig config)
    : config_(std::move(config)),
      store_((fs::create_directories(config_.dataDir), (fs::path(config_.dataDir) / "farm.sqlite").string())) {
  for (const char* sub : {"scenes", "tiles", "artifacts"}) fs::create_directories(fs::path(config_.dataDir) / sub);
  // Resume: every acknowledged tile of an unfinished job goes back into its merge.
  size_t resumed = 0;
  for (const auto& j : store_.jobs(false)) {
    for (uint64_t t : store_.doneTiles(j.id)) mergeQueue_.emplace_back(j.id, t);
    ++resumed;
  }
  if (resumed) spdlog::info("resuming {} unfinished job(s), {} acknowledged tile(s) to merge", resumed, mergeQueue_.size());
  // Tile results of jobs that ended (cancelled or failed) while the coordinator was down
  // before the merge thread removed them.
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(fs::path(config_.dataDir) / "tiles", ec)) {
    const std::string jobId = entry.path().filename().string();
    auto j = store_.job(jobId);
    if (!j || isFinal(j->state)) removeTileResults(jobId);
  }
  reaper_ = std::thread([this] { reaperLoop(); });
  mergeThread_ = std::thread([this] { mergeLoop(); });
}

Coordinator::~Coordinator() { stop(); }

void Coordinator::stop() {
  {
    std::lock_guard lock(mergeMutex_);
    if (stopping_) return;
    stopping_ = true;
  }
  mergeWake_.notify_all();
  changed_.notify_all();
  if (reaper_.joinable()) reaper_.join();
  if (mergeThread_.joinable()) mergeThread_.join();
}

void Coordinator::notify() {
  {
    std::lock_guard lock(changeMutex_);
    ++version_;
  }
  changed_.notify_all();
}

uint64_t Coordinator::waitForChange(uint64_t seen, int timeoutMs) {
  std::unique_lock lock(changeMutex_);
  changed_.wait_for(lock, std::chrono::milliseconds(timeoutMs), [&] { return version_ != seen; });
  return version_;
}

std::string Coordinator::tilePath(const std::string& jobId, uint64_t tile) const {
  return (fs::path(config_.dataDir) / "tiles" / jobId / (std::to_string(tile) + ".cpvt")).string();
}

void Coordinator::removeTileResults(const std::string& jobId) const {
  std::error_code ec;  // best effort: a leftover folder costs disk, not correctness
  fs::remove_all(fs::path(config_.dataDir) / "tiles" / jobId, ec);
}

std::string Coordinator::artifactFile(const std::string& jobId) const {
  return (fs::path(config_.dataDir) / "artifacts" / (jobId + ".cpvs")).string();
}

// --- scenes ---------------------------------------------------------------------------

pb::UploadStatus Coordinator::uploadStatus(const std::string& hash) {
  checkHashText(hash, "scene_hash");
  pb::UploadStatus s;
  s.set_scene_hash(hash);
  if (auto r = store_.scene(hash)) {
    s.set_known(true);
    s.set_received(r->received);
    s.set_total_size(r->totalSize);
    s.set_complete(r->complete);
  }
  return s;
}

void Coordinator::beginUpload(const pb::UploadSceneChunk& first) {
  checkHashText(first.scene_hash(), "scene_hash");
  std::string ext = safeExtension(first.file_name());
  if (first.total_size() == 0) throw FarmError(ErrorKind::InvalidArgument, "the scene file is empty");
  if (first.total_size() > config_.maxUploadBytes)
    throw FarmError(ErrorKind::ResourceExhausted, "the scene is " + std::to_string(first.total_size()) +
                                                      " bytes; the limit is " + std::to_string(config_.maxUploadBytes));
  std::lock_guard lock(uploadMutex_);
  auto r = store_.scene(first.scene_hash());
  if (r && r->complete) return;  // known: nothing to do
  if (r && (r->totalSize != first.total_size() || r->fileName != first.file_name())) {
    // A different announcement for the same hash: start over.
    fs::remove(fs::path(config_.dataDir) / "scenes" / (first.scene_hash() + ".part"));
    r.reset();
  }
  SceneRecord rec = r ? *r : SceneRecord{first.scene_hash(), first.file_name(), "", first.total_size(), 0, 0, false};
  if (first.offset() != rec.received)
    throw FarmError(ErrorKind::FailedPrecondition, "upload of " + rec.hash + " must resume at byte " +
                                                       std::to_string(rec.received) + ", not " +
                                                       std::to_string(first.offset()));
  store_.putScene(rec);
}

void Coordinator::appendUpload(const std::string& hash, uint64_t offset, const std::string& data) {
  std::lock_guard lock(uploadMutex_);
  auto r = store_.scene(hash);
  if (!r) throw FarmError(ErrorKind::NotFound, "no upload of scene " + hash + " was started");
  if (r->complete) return;
  if (offset != r->received)
    throw FarmError(ErrorKind::InvalidArgument, "chunk at byte " + std::to_string(offset) + ", expected " +
                                                    std::to_string(r->received));
  if (r->received + data.size() > r->totalSize)
    throw FarmError(ErrorKind::InvalidArgument, "the upload runs past its announced size of " +
                                                    std::to_string(r->totalSize) + " bytes");
  fs::path part = fs::path(config_.dataDir) / "scenes" / (hash + ".part");
  std::ofstream out(part, std::ios::binary | std::ios::app);
  out.write(data.data(), std::streamsize(data.size()));
  out.flush();
  if (!out) throw FarmError(ErrorKind::Internal, "cannot write " + part.string());
  r->received += data.size();
  store_.putScene(*r);
}

pb::UploadSceneReply Coordinator::endUpload(const std::string& hash) {
  std::lock_guard lock(uploadMutex_);
  auto r = store_.scene(hash);
  if (!r) throw FarmError(ErrorKind::NotFound, "no upload of scene " + hash + " was started");
  pb::UploadSceneReply reply;
  reply.set_scene_hash(hash);
  reply.set_received(r->received);
  if (r->complete) {
    reply.set_complete(true);
    reply.set_triangles(r->triangles);
    return reply;
  }
  if (r->received < r->totalSize) return reply;  // resumable later
  fs::path part = fs::path(config_.dataDir) / "scenes" / (hash + ".part");
  std::vector<uint8_t> bytes = readFile(part.string());
  std::string got = contentHash(bytes.data(), bytes.size()).hex();
  if (got != hash) {
    fs::remove(part);
    store_.putScene(SceneRecord{hash, r->fileName, "", r->totalSize, 0, 0, false});
    throw FarmError(ErrorKind::DataLoss, "the uploaded bytes hash to " + got + ", not " + hash + "; upload again");
  }
  fs::path final = fs::path(config_.dataDir) / "scenes" / (hash + safeExtension(r->fileName));
  fs::rename(part, final);
  try {
    SceneStats stats;
    Scene scene = loadScene(final.string(), &stats);
    r->triangles = stats.triangles;
    r->geometryHash = sceneHash(scene).hex();
  } catch (const InputError& e) {
    fs::remove(final);
    store_.putScene(SceneRecord{hash, r->fileName, "", r->totalSize, 0, 0, false});
    // The importer names the stored file: the caller is told its own file name instead,
    // not where the data folder is.
    std::string why = e.what();
    const std::string stored = final.string();
    for (size_t at = why.find(stored); at != std::string::npos; at = why.find(stored, at + r->fileName.size()))
      why.replace(at, stored.size(), r->fileName);
    throw FarmError(ErrorKind::InvalidArgument, "the scene does not import: " + why);
  }
  r->complete = true;
  store_.putScene(*r);
  spdlog::info("scene {} ({}, {} bytes, {} triangles) stored", hash, r->fileName, r->totalSize, r->triangles);
  reply.set_complete(true);
  reply.set_triangles(r->triangles);
  return reply;
}

std::string Coordinator::scenePath(const std::string& hash, std::string* fileName) {
  checkHashText(hash, "scene_hash");
  auto r = store_.scene(hash);
  if (!r || !r->complete) throw FarmError(ErrorKind::NotFound, "scene " + hash + " is not on the server");
  if (fileName) *fileName = r->fileName;
  return (fs::path(config_.dataDir) / "scenes" / (hash + safeExtension(r->fileName))).string();
}

// --- jobs -----------------------------------------------------------------------------

pb::JobStatus Coordinator::toStatus(const JobRecord& j) const {
  pb::JobStatus s;
  s.set_job_id(j.id);
  s.set_request_id(j.requestId);
  s.set_state(pb::JobState(int(j.state)));
  s.mutable_spec()->ParseFromString(j.spec);
  s.set_tiles_total(j.tilesTotal);
  s.set_tiles_done(j.tilesDone);
  for (const auto& [stage, seconds] : j.stages) {
    auto* st = s.add_stages();
    st->set_stage(stage);
    st->set_seconds(seconds);
  }
  int64_t end = isFinal(j.state) && j.finishedMs ? j.finishedMs : nowMs();
  double elapsed = double(end - j.createdMs) / 1000.0;
  s.set_seconds_elapsed(elapsed);
  double eta = -1;
  if (j.state == JobState::Running && j.tilesDone > 0 && j.startedMs > 0) {
    double running = double(nowMs() - j.startedMs) / 1000.0;
    eta = running * double(j.tilesTotal - j.tilesDone) / double(j.tilesDone);
  }
  s.set_eta_seconds(isFinal(j.state) ? 0 : eta);
  s.set_error(j.error);
  s.set_bytes(j.bytes);
  s.set_file_bytes(j.fileBytes);
  s.set_resolution(j.resolution);
  s.set_peak_merge_bytes(j.peakMergeBytes);
  s.set_created_unix_ms(j.createdMs);
  return s;
}

pb::JobStatus Coordinator::submit(const pb::SubmitBakeRequest& request) {
  const pb::BakeSpec& spec = request.spec();
  if (request.request_id().empty() || request.request_id().size() > 128)
    throw FarmError(ErrorKind::InvalidArgument, "request_id must be 1..128 characters");
  // The job this request id already names, if any: the same spec is a retry.
  auto known = [&]() -> std::optional<pb::JobStatus> {
    auto existing = store_.jobByRequest(request.request_id());
    if (!existing) return std::nullopt;
    if (existing->spec != spec.SerializeAsString())
      throw FarmError(ErrorKind::AlreadyExists,
                      "request_id " + request.request_id() + " was used for a different job (" + existing->id + ")");
    return toStatus(*existing);
  };
  if (auto existing = known()) return *existing;
  if (spec.name().size() > 256) throw FarmError(ErrorKind::InvalidArgument, "name is longer than 256 characters");
  if (std::abs(spec.priority()) > 1000) throw FarmError(ErrorKind::InvalidArgument, "priority must be in -1000..1000");
  JobRecord j;
  LightFrame frame;
  BakeOptions options;
  int log2R = 0;
  try {
    frame = net::lightOf(spec);
    options = net::fromProto(spec.options());
    log2R = parseResolution(spec.resolution());
  } catch (const InputError& e) {
    throw FarmError(ErrorKind::InvalidArgument, e.what());
  }
  if (log2R < config_.minLog2Resolution || log2R > config_.maxLog2Resolution)
    throw FarmError(ErrorKind::InvalidArgument, "resolution " + spec.resolution() + " is outside this farm's limits (" +
                                                    std::to_string(1ull << config_.minLog2Resolution) + " .. " +
                                                    std::to_string(1ull << config_.maxLog2Resolution) + ")");
  auto checkRoom = [&] {
    if (store_.activeJobCount() >= config_.maxActiveJobs)
      throw FarmError(ErrorKind::ResourceExhausted,
                      "the farm already holds " + std::to_string(config_.maxActiveJobs) + " unfinished jobs");
  };
  checkRoom();  // before loading the scene, which may take long
  std::string path = scenePath(spec.scene_hash(), nullptr);
  Scene scene = loadScene(path);
  OrthoGrid grid;
  try {
    grid = makeGrid(scene, frame, log2R);
  } catch (const InputError& e) {
    throw FarmError(ErrorKind::InvalidArgument, e.what());
  }
  j.id = randomId("j");
  j.requestId = request.request_id();
  j.sceneHash = spec.scene_hash();
  j.geometryHash = sceneHash(scene).hex();
  j.spec = spec.SerializeAsString();
  j.grid = net::toProto(grid).SerializeAsString();
  j.options = net::toProto(options).SerializeAsString();
  j.priority = spec.priority();
  j.createdMs = nowMs();
  j.resolution = grid.resolution();
  j.tilesPerSide = TilePlan(log2R, options.log2TileSize).perSide();
  j.tilesTotal = j.tilesPerSide * j.tilesPerSide;
  {
    // Checked again and created under one lock: a retry that arrives while its first call
    // is still loading the scene gets the same job (not a unique-key error), and calls
    // submitted at once cannot together exceed the job limit. The tile folder exists
    // before a worker can lease a tile of the job.
    std::lock_guard lock(submitMutex_);
    if (auto existing = known()) return *existing;
    checkRoom();
    fs::create_directories(fs::path(config_.dataDir) / "tiles" / j.id);
    store_.createJob(j);
  }
  spdlog::info("job {} submitted: scene {}, {}^3, {} tiles", j.id, j.sceneHash, j.resolution, j.tilesTotal);
  notify();
  return status(j.id);
}

pb::JobStatus Coordinator::status(const std::string& jobId) {
  auto j = store_.job(jobId);
  if (!j) throw FarmError(ErrorKind::NotFound, "no job " + jobId);
  return toStatus(*j);
}

std::vector<pb::JobStatus> Coordinator::list(bool includeFinished) {
  std::vector<pb::JobStatus> out;
  for (const auto& j : store_.jobs(includeFinished)) out.push_back(toStatus(j));
  return out;
}

pb::JobStatus Coordinator::cancel(const std::string& jobId) {
  auto j = store_.job(jobId);
  if (!j) throw FarmError(ErrorKind::NotFound, "no job " + jobId);
  if (endJob(jobId, JobState::Cancelled, "cancelled")) spdlog::info("job {} cancelled", jobId);
  return status(jobId);
}

std::string Coordinator::artifactPath(const std::string& jobId, std::string* checksum) {
  auto j = store_.job(jobId);
  if (!j) throw FarmError(ErrorKind::NotFound, "no job " + jobId);
  if (j->state != JobState::Done)
    throw FarmError(ErrorKind::FailedPrecondition,
                    "job " + jobId + " is " + net::jobStateName(pb::JobState(int(j->state))) + ", not done");
  if (checksum) *checksum = j->artifactChecksum;
  return artifactFile(jobId);
}

void Coordinator::failJob(const std::string& jobId, const std::string& error) {
  if (endJob(jobId, JobState::Failed, error)) spdlog::warn("job {} failed: {}", jobId, error);
}

bool Coordinator::endJob(const std::string& jobId, JobState state, const std::string& why) {
  {
    // Under the result lock, so that no result of the job is written after its tiles are
    // cancelled: completeTile takes only tiles still waiting for one.
    std::lock_guard resultLock(resultMutex_);
    auto j = store_.job(jobId);
    if (!j || isFinal(j->state)) return false;  // the first end stands (cancel vs a late failure)
    store_.setJobState(jobId, state, why, nowMs());
    store_.cancelTiles(jobId);
  }
  {
    // Its tile results are removed by the merge thread, after any merge of them queued
    // before: the merge never finds a file gone under it.
    std::lock_guard lock(mergeMutex_);
    mergeQueue_.emplace_back(jobId, kRemoveTiles);
  }
  mergeWake_.notify_all();
  notify();
  return true;
}

// --- workers --------------------------------------------------------------------------

pb::TileLease Coordinator::lease(const std::string& workerId) {
  if (workerId.empty() || workerId.size() > 128)
    throw FarmError(ErrorKind::InvalidArgument, "worker_id must be 1..128 characters");
  pb::TileLease out;
  int64_t now = nowMs();
  int64_t deadline = now + int64_t(config_.leaseSeconds * 1000);
  auto l = store_.leaseNextTile(workerId, randomId("l"), now, deadline);
  if (!l) {
    out.set_granted(false);
    out.set_retry_after_ms(500);
    return out;
  }
  auto j = store_.job(l->jobId);
  out.set_granted(true);
  out.set_lease_id(l->leaseId);
  out.set_job_id(l->jobId);
  out.set_tile_index(l->tile);
  out.set_tile_x(l->tile % j->tilesPerSide);
  out.set_tile_y(l->tile / j->tilesPerSide);
  out.set_scene_hash(j->sceneHash);
  out.mutable_grid()->ParseFromString(j->grid);
  out.mutable_options()->ParseFromString(j->options);
  out.set_deadline_unix_ms(deadline);
  notify();
  return out;
}

pb::RenewReply Coordinator::renew(const std::string& leaseId) {
  pb::RenewReply r;
  int64_t deadline = nowMs() + int64_t(config_.leaseSeconds * 1000);
  r.set_valid(store_.renewLease(leaseId, deadline));
  r.set_deadline_unix_ms(r.valid() ? deadline : 0);
  return r;
}

bool Coordinator::completeTile(const std::string& leaseId, const std::string& encoded,
                               const std::map<std::string, double>& stages) {
  auto l = store_.lease(leaseId);
  if (!l) throw FarmError(ErrorKind::NotFound, "no lease " + leaseId);
  auto j = store_.job(l->jobId);
  if (!j || isFinal(j->state)) return false;
  pb::BakeOptions po;
  po.ParseFromString(j->options);
  BakeOptions options = net::fromProto(po);
  std::string source = "tile " + std::to_string(l->tile) + " of job " + l->jobId;
  try {
    Dag dag = decodeSubDag(reinterpret_cast<const uint8_t*>(encoded.data()), encoded.size(), source,
                           options.compress != CompressMode::None, options.hash);
    if (dag.log2Resolution != int(std::log2(double(j->resolution))))
      throw InputError(source + ": resolution does not match the job");
    checkTileRoots(dag, l->tile % j->tilesPerSide, l->tile / j->tilesPerSide,
                   std::min(options.log2TileSize, dag.log2Resolution), source);
  } catch (const InputError& e) {
    throw FarmError(ErrorKind::InvalidArgument, std::string("rejected result: ") + e.what());
  }
  // The file first, then the acknowledgement: a tile marked done always has its bytes.
  // Both under one lock, and only for a tile still waiting for its result: a declined
  // result (a late or duplicate lease) must not replace the file of the one taken, which
  // the merge, and a restart's merge, read; and two results for one tile must not write
  // the same temporary file at once.
  std::lock_guard resultLock(resultMutex_);
  auto state = store_.tileState(l->jobId, l->tile);
  if (!state || (*state != TileState::Queued && *state != TileState::Leased)) return false;
  std::vector<uint8_t> bytes(encoded.begin(), encoded.end());
  try {
    writeFileAtomic(tilePath(l->jobId, l->tile), bytes);
  } catch (const InputError& e) {
    // The coordinator's own disk (full, read-only): not the worker's fault, and the tile
    // stays leased, so the worker's report or the lease's expiry puts it back in the queue.
    throw FarmError(ErrorKind::Internal, std::string("the coordinator cannot store the result: ") + e.what());
  }
  if (!store_.completeTile(l->jobId, l->tile)) return false;
  store_.addStageSeconds(l->jobId, stages);
  auto after = store_.job(l->jobId);
  if (after && after->tilesDone == after->tilesTotal) store_.setJobState(l->jobId, JobState::Merging, "", nowMs());
  {
    std::lock_guard lock(mergeMutex_);
    mergeQueue_.emplace_back(l->jobId, l->tile);
  }
  mergeWake_.notify_all();
  notify();
  return true;
}

void Coordinator::failTile(const std::string& leaseId, const std::string& reason) {
  auto l = store_.lease(leaseId);
  if (!l) throw FarmError(ErrorKind::NotFound, "no lease " + leaseId);
  if (l->deadlineMs == 0) return;  // no longer the tile's current lease
  int attempts = store_.requeueTile(l->jobId, l->tile, reason);
  spdlog::warn("tile {} of job {} failed on {} (attempt {}): {}", l->tile, l->jobId, l->workerId, attempts, reason);
  if (attempts >= config_.maxAttempts)
    failJob(l->jobId, "tile " + std::to_string(l->tile) + " failed " + std::to_string(attempts) + " times: " + reason);
  notify();
}

void Coordinator::reaperLoop() {
  for (;;) {
    {
      std::unique_lock lock(mergeMutex_);
      mergeWake_.wait_for(lock, std::chrono::milliseconds(250), [&] { return stopping_; });
      if (stopping_) return;
    }
    for (const auto& [jobId, tile, attempts] : store_.expireLeases(nowMs())) {
      spdlog::warn("lease on tile {} of job {} expired (attempt {})", tile, jobId, attempts);
      if (attempts >= config_.maxAttempts)
        failJob(jobId, "tile " + std::to_string(tile) + ": lease expired " + std::to_string(attempts) + " times");
      notify();
    }
  }
}

// --- the streaming merge ----------------------------------------------------------------

void Coordinator::mergeLoop() {
  for (;;) {
    std::pair<std::string, uint64_t> item;
    {
      std::unique_lock lock(mergeMutex_);
      mergeWake_.wait(lock, [&] { return stopping_ || !mergeQueue_.empty(); });
      if (stopping_) return;
      item = mergeQueue_.front();
      mergeQueue_.pop_front();
    }
    try {
      mergeOne(item.first, item.second);
    } catch (const std::exception& e) {
      failJob(item.first, std::string("merge failed: ") + e.what());
      merges_.erase(item.first);
    }
  }
}

void Coordinator::mergeOne(const std::string& jobId, uint64_t tile) {
  if (tile == kRemoveTiles) {
    merges_.erase(jobId);
    removeTileResults(jobId);
    return;
  }
  auto j = store_.job(jobId);
  if (!j || isFinal(j->state)) {
    merges_.erase(jobId);
    return;
  }
  pb::BakeOptions po;
  po.ParseFromString(j->options);
  BakeOptions options = net::fromProto(po);
  MergeState& m = merges_[jobId];
  if (!m.merger) m.merger = std::make_unique<StreamingMerger>(options.compress);
  auto start = std::chrono::steady_clock::now();
  std::vector<uint8_t> bytes = readFile(tilePath(jobId, tile));
  Dag dag = decodeSubDag(bytes.data(), bytes.size(), tilePath(jobId, tile), options.compress != CompressMode::None,
                         options.hash);
  m.merger->add(std::move(dag));
  ++m.merged;
  m.peak = std::max(m.peak, m.merger->heldBytes());
  store_.addStageSeconds(jobId, {{"merge", secondsSince(start)}});
  if (m.merged == j->tilesTotal) {
    finishJob(jobId, m);
    merges_.erase(jobId);
  }
}

void Coordinator::finishJob(const std::string& jobId, MergeState& m) {
  auto j = store_.job(jobId);
  pb::BakeOptions po;
  po.ParseFromString(j->options);
  pb::GridSpec pg;
  pg.ParseFromString(j->grid);
  auto start = std::chrono::steady_clock::now();
  CpvsArtifact art;
  art.grid = net::fromProto(pg);
  art.options = net::fromProto(po);
  art.sceneHash = parseHashHex(j->geometryHash, "geometry hash");
  art.dag = assembleRoots(*m.merger->finish(), art.options.hash, art.options.compress);
  store_.addStageSeconds(jobId, {{"merge", secondsSince(start)}});
  start = std::chrono::steady_clock::now();
  std::vector<uint8_t> file = encodeCpvs(art, true);
  writeFileAtomic(artifactFile(jobId), file);
  std::string checksum = contentHash(file.data(), file.size()).hex();
  store_.addStageSeconds(jobId, {{"write", secondsSince(start)}});
  store_.finishJob(jobId, art.dag.bytes(), file.size(), m.peak, checksum, nowMs());
  removeTileResults(jobId);
  spdlog::info("job {} done: {} bytes (file {}), peak merge memory {} bytes", jobId, art.dag.bytes(), file.size(),
               m.peak);
  notify();
}

}  // namespace cpvs::server
