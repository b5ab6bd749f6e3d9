#include "tile_worker.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <optional>
#include <thread>
#include <vector>

#include "cpvs/scene/import.h"
#include "cpvs/bake/bake.h"
#include "cpvs/bake/bake_lights.h"
#include "cpvs/base/error.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/text.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/bake/bake_dag_mh.h"
#include "cpvs/io/dmh_tile_file.h"
#include "cpvs/io/sub_dag_file.h"
#include "cpvs/net/chunked_stream.h"
#include "cpvs/bake/tile_key.h"
#include "cpvs/net/convert.h"
#include "cpvs/net/model_convert.h"
#include "cpvs/net/receiver_declaration.h"
#include "cpvs/net/status.h"

namespace cpvs::worker {

namespace fs = std::filesystem;

namespace {

/// A failed RPC that the pull loop answers by backing off and retrying.
struct Unreachable : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// A failure that is not the tile's: the coordinator is told so and does not count it
/// against the tile's attempts (R10, R4).
struct WorkerFault : std::runtime_error {
  WorkerFault(pb::FailKind k, const std::string& what) : std::runtime_error(what), kind(k) {}
  pb::FailKind kind;
};

void check(const grpc::Status& s, const char* rpc) {
  if (s.ok()) return;
  if (s.error_code() == grpc::StatusCode::UNAVAILABLE || s.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED)
    throw Unreachable(std::string(rpc) + ": " + net::describe(s));
  throw std::runtime_error(std::string(rpc) + ": " + net::describe(s));
}

}  // namespace

TileWorker::TileWorker(WorkerConfig config) : config_(std::move(config)), metrics_(config_.slots) {
  channel_ = net::makeChannel(config_.server);
  stub_ = pb::Workers::NewStub(channel_);
  fs::create_directories(config_.cacheDir);
  std::error_code ec;
  fs::remove(alivePath(config_.cacheDir), ec);  // an earlier run's contact is not this one's
  if (config_.tileCacheMb > 0)
    tileCache_ = std::make_unique<TileCache>((fs::path(config_.cacheDir) / "tiles").string(), config_.tileCacheMb << 20);
}

std::string alivePath(const std::string& cacheDir) { return (fs::path(cacheDir) / ".alive").string(); }

void TileWorker::noteContact() {
  // At most every 5 s: every slot's lease and renewal would otherwise touch it.
  const int64_t now = std::chrono::duration_cast<std::chrono::milliseconds>(
                          std::chrono::steady_clock::now().time_since_epoch()).count();
  int64_t last = lastContactMs_;
  if (now - last < 5000 || !lastContactMs_.compare_exchange_strong(last, now)) return;
  std::ofstream(alivePath(config_.cacheDir), std::ios::trunc) << "the coordinator answered\n";
}

void TileWorker::run() {
  std::vector<std::thread> threads;
  for (int s = 0; s < config_.slots; ++s) threads.emplace_back([this, s] { slotLoop(s); });
  for (auto& t : threads) t.join();
}

void TileWorker::slotLoop(int slot) {
  int backoffMs = 200;
  while (!stopping_) {
    if (config_.maxTiles > 0 && tilesStarted_ >= uint64_t(config_.maxTiles)) return;
    try {
      pb::LeaseRequest req;
      req.set_worker_id(config_.workerId + "/" + std::to_string(slot));
      pb::TileLease lease;
      grpc::ClientContext ctx;
      net::prepare(ctx, config_.server, 10);
      check(stub_->LeaseTile(&ctx, req, &lease), "LeaseTile");
      noteContact();
      backoffMs = 200;
      if (!lease.granted()) {
        std::this_thread::sleep_for(std::chrono::milliseconds(std::clamp<uint32_t>(lease.retry_after_ms(), 50, 5000)));
        continue;
      }
      ++tilesStarted_;
      {
        std::lock_guard lock(inFlightMutex_);
        inFlight_.emplace(lease.lease_id(), lease);
      }
      metrics_.slotBusy(+1);
      struct Done {
        TileWorker& w;
        const std::string& leaseId;
        ~Done() {
          w.metrics_.slotBusy(-1);
          std::lock_guard lock(w.inFlightMutex_);
          w.inFlight_.erase(leaseId);
        }
      } done{*this, lease.lease_id()};
      bakeLeased(lease);
    } catch (const Unreachable& e) {
      metrics_.unreachable();
      spdlog::warn("coordinator unreachable ({}); retrying in {} ms", e.what(), backoffMs);
      std::this_thread::sleep_for(std::chrono::milliseconds(backoffMs));
      backoffMs = std::min(backoffMs * 2, 10000);
    } catch (const std::exception& e) {
      spdlog::error("{}", e.what());
      std::this_thread::sleep_for(std::chrono::milliseconds(backoffMs));
      backoffMs = std::min(backoffMs * 2, 10000);
    }
  }
}

size_t TileWorker::releaseInFlight() {
  abandon();
  std::map<std::string, pb::TileLease> leases;
  {
    std::lock_guard lock(inFlightMutex_);
    leases.swap(inFlight_);  // their bakes, when they end, find them given back
  }
  for (const auto& [id, lease] : leases) {
    release(lease, "worker stopping", pb::FAIL_INTERRUPTED);
    metrics_.tileEnded("given_back");
  }
  return leases.size();
}

void TileWorker::bakeLeased(const pb::TileLease& lease) {
  if (lease.grid().projection() == v1::PROJECTION_PERSPECTIVE)
    spdlog::info("tile {} ({}, {}) of light {}'s grid {} of job {}: baking", lease.tile_index(), lease.tile_x(),
                 lease.tile_y(), lease.light(), lease.grid_index(), lease.job_id());
  else
    spdlog::info("tile {} ({}, {}) of job {}: baking", lease.tile_index(), lease.tile_x(), lease.tile_y(), lease.job_id());
  // Renew the lease in the background while the tile bakes: at a third of its length.
  std::mutex m;
  std::condition_variable cv;
  bool done = false;
  std::atomic<bool> lost{false};
  std::thread renewer([&] {
    // A third of the lease's length, measured from each reply on this machine's steady
    // clock (R11): the deadline is the coordinator's wall clock, which this one may not
    // share. A coordinator that sends no length leaves the deadline as the only guide.
    const auto periodOf = [](uint32_t leaseMs, int64_t deadlineUnixMs) {
      if (leaseMs > 0) return std::max<int64_t>(100, int64_t(leaseMs) / 3);
      const int64_t wallNow =
          std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch())
              .count();
      return std::max<int64_t>(200, (deadlineUnixMs - wallNow) / 3);
    };
    int64_t periodMs = periodOf(lease.lease_ms(), lease.deadline_unix_ms());
    std::unique_lock lock(m);
    while (!cv.wait_for(lock, std::chrono::milliseconds(periodMs), [&] { return done; })) {
      pb::RenewRequest req;
      req.set_lease_id(lease.lease_id());
      pb::RenewReply reply;
      grpc::ClientContext ctx;
      net::prepare(ctx, config_.server, 10);
      if (stub_->RenewLease(&ctx, req, &reply).ok()) {
        noteContact();
        if (!reply.valid()) {
          lost = true;  // expired or the job ended: the result will likely be declined
          return;
        }
        periodMs = periodOf(reply.lease_ms(), reply.deadline_unix_ms());
      }
    }
  });
  auto stopRenewing = [&] {
    {
      std::lock_guard lock(m);
      done = true;
    }
    cv.notify_all();
    renewer.join();
  };
  try {
    BakeOptions options = net::fromProto(lease.options());
    // The hash names files in the cache: 32 hex digits, nothing a path could be made of (R23).
    parseHashHex(lease.scene_hash(), "the lease's scene_hash");
    auto prepared = bakeScene(lease.scene_hash(), lease.grid(), options.renderer, lease.options().receivers(),
                              {lease.exclude().begin(), lease.exclude().end()});
    StageTimes times;
    // The tile cache keeps sub-DAGs: a DAG-MH job's tiles are baked each time.
    const bool dagMh = lease.format() == pb::ARTIFACT_FORMAT_DAG_MH;
    const std::optional<Hash128> key =
        tileCache_ && !dagMh ? tileKey(*prepared, options, lease.tile_x(), lease.tile_y()) : std::nullopt;
    std::optional<std::vector<uint8_t>> kept =
        key ? tileCache_->findFile(*key, lease.tile_x(), lease.tile_y(), options) : std::nullopt;
    std::vector<uint8_t> encoded;
    const bool reused = kept.has_value();
    if (reused) {  // this tile's content was baked before, here: its sub-DAG as it was sent then
      encoded = std::move(*kept);
      ++tilesReused_;
      spdlog::info("tile {} of job {}: its content was baked before, sent from the tile cache", lease.tile_index(),
                   lease.job_id());
    } else if (dagMh) {  // the parts of a DAG-MH (seed 001) the coordinator's builder merges
      std::vector<DagMhTile> parts = bakeDagMhFarmTile(*prepared, options, lease.tile_x(), lease.tile_y(), &times);
      auto start = std::chrono::steady_clock::now();
      encoded = encodeDagMhTiles(parts, true);
      times.add("encode", secondsSince(start));
    } else {
      Dag dag = bakeTile(*prepared, lease.tile_x(), lease.tile_y(), options, &times);
      auto start = std::chrono::steady_clock::now();
      encoded = encodeSubDag(dag, true);
      times.add("encode", secondsSince(start));
      if (key) tileCache_->storeFile(*key, encoded);
    }
    if (abandoning_) {
      stopRenewing();
      bool held;
      {
        std::lock_guard lock(inFlightMutex_);
        held = inFlight_.erase(lease.lease_id()) > 0;
      }
      if (held) {
        release(lease, "worker stopping", pb::FAIL_INTERRUPTED);
        metrics_.tileEnded("given_back");
      }
      return;
    }
    // The lease is renewed while the result is sent, and sent again (a coordinator
    // restarting, or out of disk for a while): it must not expire under a finished tile.
    deliverResult(lease, encoded, times.seconds, reused);
    stopRenewing();
    ++tilesDone_;
    metrics_.tileEnded("returned", times.seconds);
    if (lost) spdlog::warn("tile {} of job {}: the lease was lost while baking", lease.tile_index(), lease.job_id());
  } catch (const Unreachable&) {
    if (renewer.joinable()) stopRenewing();
    metrics_.tileEnded("lost");
    throw;
  } catch (const WorkerFault& e) {
    if (renewer.joinable()) stopRenewing();
    spdlog::error("tile {} of job {} given back: {}", lease.tile_index(), loggable(lease.job_id()), loggable(e.what(), 1000));
    release(lease, e.what(), e.kind);
    metrics_.tileEnded("given_back");
  } catch (const std::exception& e) {
    if (renewer.joinable()) stopRenewing();
    spdlog::error("tile {} of job {} failed: {}", lease.tile_index(), loggable(lease.job_id()), loggable(e.what(), 1000));
    release(lease, e.what());
    metrics_.tileEnded("failed");
  }
}

void TileWorker::deliverResult(const pb::TileLease& lease, const std::vector<uint8_t>& encoded,
                               const std::map<std::string, double>& stages, bool reused) {
  // A baked tile is not thrown away because the coordinator is briefly unreachable (a
  // restart keeps the lease in its store, and CompleteTile may be sent again): retried
  // with backoff for up to two minutes, then given up as before (R17).
  const auto giveUp = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  int backoffMs = 200;
  for (;;) {
    try {
      sendResult(lease, encoded, stages, reused);
      return;
    } catch (const Unreachable& e) {
      if (abandoning_ || std::chrono::steady_clock::now() + std::chrono::milliseconds(backoffMs) > giveUp) throw;
      spdlog::warn("tile {} of job {}: {}; sending it again in {} ms", lease.tile_index(), loggable(lease.job_id()),
                   e.what(), backoffMs);
      std::this_thread::sleep_for(std::chrono::milliseconds(backoffMs));
      backoffMs = std::min(backoffMs * 2, 5000);
    }
  }
}

void TileWorker::sendResult(const pb::TileLease& lease, const std::vector<uint8_t>& encoded,
                            const std::map<std::string, double>& stages, bool reused) {
  grpc::ClientContext ctx;
  net::prepare(ctx, config_.server, 600);
  pb::CompleteReply reply;
  auto writer = stub_->CompleteTile(&ctx, &reply);
  // When the coordinator ends the call early, Finish says why.
  net::sendChunks<pb::TileResultChunk>(net::ChunkSource::ofBytes(encoded.data(), encoded.size()), 0, *writer,
                                       [&](pb::TileResultChunk& chunk, uint64_t, bool first) {
                                         if (!first) return;
                                         chunk.set_lease_id(lease.lease_id());
                                         chunk.set_total_size(encoded.size());
                                         chunk.set_checksum(contentHash(encoded.data(), encoded.size()).hex());
                                         chunk.set_reused(reused);
                                         for (const auto& [stage, seconds] : stages) {
                                           auto* s = chunk.add_stages();
                                           s->set_stage(stage);
                                           s->set_seconds(seconds);
                                         }
                                       });
  writer->WritesDone();
  check(writer->Finish(), "CompleteTile");
  spdlog::info("tile {} of job {}: {} bytes returned{}", lease.tile_index(), lease.job_id(), encoded.size(),
               reply.accepted() ? "" : " (declined: another result was taken)");
}

void TileWorker::release(const pb::TileLease& lease, const std::string& reason, pb::FailKind kind) {
  pb::FailRequest req;
  req.set_lease_id(lease.lease_id());
  req.set_reason(reason);
  req.set_kind(kind);
  pb::FailReply reply;
  grpc::ClientContext ctx;
  net::prepare(ctx, config_.server, 10);
  grpc::Status s = stub_->FailTile(&ctx, req, &reply);
  if (!s.ok()) spdlog::warn("could not release tile {}: {}", lease.tile_index(), net::describe(s));
}

Scene TileWorker::importScene(const std::string& sceneHash) {
  // The coordinator imported the upload in its sandbox; a worker does not trust it more
  // for that: assimp runs in cpvs-import here too.
  const std::string path = fetchScene(sceneHash);
  try {
    return importIsolated(path, config_.import, nullptr, nullptr);
  } catch (const InputError&) {
    throw;  // the file: the tile fails
  } catch (const std::exception& e) {
    // The importer could not run here (missing, no process or pipe): this worker's
    // trouble, not the tile's.
    throw WorkerFault(pb::FAIL_WORKER, "importing scene " + sceneHash + ": " + e.what());
  }
}

std::string TileWorker::fetchScene(const std::string& sceneHash) {
  try {
    return fetchSceneOnce(sceneHash);
  } catch (const Unreachable&) {
    throw;
  } catch (const WorkerFault&) {
    throw;
  } catch (const std::exception& e) {
    // The cache folder (full, read-only) or the transfer: nothing the tile did.
    throw WorkerFault(pb::FAIL_WORKER, std::string("fetching scene ") + sceneHash + ": " + e.what());
  }
}

std::string TileWorker::fetchSceneOnce(const std::string& sceneHash) {
  std::lock_guard lock(fetchMutex_);
  for (const auto& e : fs::directory_iterator(config_.cacheDir)) {
    if (e.path().stem() != sceneHash || e.path().extension() == ".part") continue;
    // A cached file is read once per process (the scene stays in memory): checked then,
    // so that a file damaged on the worker's disk is fetched again, not baked (R23).
    const std::vector<uint8_t> cached = readFile(e.path().string());
    if (contentHash(cached.data(), cached.size()).hex() == sceneHash) return e.path().string();
    spdlog::warn("cached scene {} fails its hash: fetching it again", sceneHash);
    fs::remove(e.path());
    break;
  }
  fs::path part = fs::path(config_.cacheDir) / (sceneHash + ".part");
  uint64_t offset = fs::exists(part) ? fs::file_size(part) : 0;
  std::string fileName;
  {
    pb::FetchSceneRequest req;
    req.set_scene_hash(sceneHash);
    req.set_offset(offset);
    grpc::ClientContext ctx;
    net::prepare(ctx, config_.server, 600);
    auto reader = stub_->FetchScene(&ctx, req);
    net::ChunkReceiver receiver(offset, UINT64_MAX, net::ErrorKind::DataLoss, "the scene " + sceneHash);
    AppendFile out(part.string());
    pb::SceneChunk chunk;
    while (reader->Read(&chunk)) {
      receiver.accept(chunk.total_size(), chunk.offset(), chunk.data().size());
      out.write(chunk.data().data(), chunk.data().size());
      fileName = chunk.file_name();
    }
    out.syncAndClose();
    const grpc::Status s = reader->Finish();
    // The coordinator cannot serve its copy: let it check that copy.
    if (s.error_code() == grpc::StatusCode::NOT_FOUND || s.error_code() == grpc::StatusCode::DATA_LOSS)
      throw WorkerFault(pb::FAIL_SCENE_DAMAGED, "FetchScene: " + net::describe(s));
    check(s, "FetchScene");
    receiver.finish();
  }
  std::vector<uint8_t> bytes = readFile(part.string());
  if (contentHash(bytes.data(), bytes.size()).hex() != sceneHash) {
    fs::remove(part);
    throw WorkerFault(pb::FAIL_SCENE_DAMAGED, "scene " + sceneHash + " arrived damaged (hash mismatch)");
  }
  fs::path final = fs::path(config_.cacheDir) / (sceneHash + fs::path(fileName).extension().string());
  fs::rename(part, final);
  syncParentFolder(final.string());
  spdlog::info("scene {} fetched ({} bytes)", sceneHash, bytes.size());
  return final.string();
}

std::shared_ptr<BakeScene> TileWorker::bakeScene(const std::string& sceneHash, const v1::GridSpec& grid,
                                                 Renderer renderer, const v1::Receivers& receivers,
                                                 const std::vector<std::string>& exclude) {
  // Checked before anything is fetched or cached: the grid either projection makes.
  const GridSpec spec = net::gridSpecOf(grid);
  std::optional<OrthoGrid> ortho;
  std::optional<PerspectiveGrid> spot;
  if (spec.projection == Projection::Perspective)
    spot.emplace(perspectiveGridOf(spec, "grid"));
  else
    ortho = orthoGridOf(spec, "grid");
  std::shared_ptr<CachedScene> cached;
  {
    std::lock_guard lock(cacheMutex_);
    cached = cache_[sceneHash];
    if (!cached) cached = cache_[sceneHash] = std::make_shared<CachedScene>();
  }
  std::lock_guard lock(cached->mutex);
  if (cached->scene.indices.empty()) cached->scene = importScene(sceneHash);
  // Every field of the grid decides the projection; the bits of the doubles name it.
  std::string key = std::string(optionName(renderer)) + "," + std::to_string(int(grid.projection()));
  char field[32];
  for (const v1::Vec3* v : {&grid.light_dir(), &grid.frame_u(), &grid.frame_v(), &grid.origin(), &grid.position()})
    for (double x : {v->x(), v->y(), v->z()}) key += (std::snprintf(field, sizeof field, ",%a", x), field);
  for (double x : {grid.u0(), grid.v0(), grid.d0(), grid.extent(), grid.depth_extent(), grid.tan_half_fov(), grid.near(),
                   grid.far(), grid.tan_cone()})
    key += (std::snprintf(field, sizeof field, ",%a", x), field);
  key += "," + std::to_string(grid.log2_resolution());
  // The receivers as sent (kind, width, the volume's hash and boxes) decide what is freed.
  const std::string declared = receivers.SerializeAsString();
  key += "," + contentHash(declared.data(), declared.size()).hex();
  for (const std::string& name : exclude) key += "," + std::to_string(name.size()) + ":" + name;
  // A job's tiles share one grid: a handful of entries cover the jobs a worker serves
  // (slots still baking keep theirs alive).
  if (!cached->prepared.count(key) && cached->prepared.size() >= 4) cached->prepared.clear();
  auto& prepared = cached->prepared[key];
  if (!prepared) {
    auto start = std::chrono::steady_clock::now();
    const ReceiverDeclaration declaration =
        net::declarationOf(net::modelOf(receivers), [&](const std::string& hash) { return importScene(hash); });
    Scene storage;
    const Scene& casters = castersOf(cached->scene, exclude, "the lease's light", storage);
    // A light's fixture casts none of its shadows but receives as the rest of the scene.
    prepared = spot ? std::make_shared<BakeScene>(casters, *spot, spec.tanCone, renderer, config_.threads, declaration,
                                                  &cached->scene)
                    : std::make_shared<BakeScene>(cached->scene, *ortho, renderer, config_.threads, declaration);
    spdlog::info("scene {} prepared for the {} renderer in {:.2f} s", sceneHash, optionName(renderer), secondsSince(start));
  }
  return prepared;
}

}  // namespace cpvs::worker
