#include "rpc/farm_service.h"

#include "cpvs/base/error.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/text.h"
#include "cpvs/bake/stage_times.h"

#include <spdlog/spdlog.h>

#include <optional>
#include <type_traits>

#include "cpvs/net/channel.h"
#include "cpvs/net/chunked_stream.h"
#include "cpvs/net/status.h"
#include "cpvs/net/convert.h"
#include "cpvs/net/model_convert.h"

namespace cpvs::server {

namespace {

/// Largest sub-DAG a worker may send (a 4K tile of a dense scene is tens of MB).
constexpr uint64_t kMaxTileResultBytes = uint64_t(2) << 30;

/// Runs `body` after authorization, turning every error into a status: the server keeps
/// serving whatever a request holds.
template <class F>
grpc::Status guarded(const grpc::ServerContext* ctx, Gatekeeper& gate, Role needed, const char* rpc, F&& body) {
  Access access;
  grpc::Status auth = gate.admit(ctx, needed, &access);
  if (!auth.ok()) return auth;
  try {
    if constexpr (std::is_invocable_v<F, const Access&>)
      return body(access);
    else
      return body();
  } catch (const FarmError& e) {
    if (e.kind == ErrorKind::Internal) spdlog::error("{}: {}", rpc, e.what());
    return net::toGrpcStatus(e);
  } catch (const InputError& e) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, e.what());
  } catch (const StoreUnavailable& e) {
    spdlog::warn("{}: {}", rpc, e.what());
    return grpc::Status(grpc::StatusCode::UNAVAILABLE, std::string(e.what()) + "; try again");
  } catch (const std::exception& e) {
    spdlog::error("{}: internal error: {}", rpc, e.what());
    return grpc::Status(grpc::StatusCode::INTERNAL, std::string("internal error: ") + e.what());
  }
}

/// The stage names, comma-separated, for messages.
std::string stageList() {
  std::string out;
  for (const char* name : kStageNames) out += (out.empty() ? "" : ", ") + std::string(name);
  return out;
}

/// Streams a stored file from `offset`; `fill` completes each message.
template <class Msg, class Fill>
grpc::Status streamFile(const std::string& path, uint64_t offset, grpc::ServerWriter<Msg>* writer, Fill&& fill) {
  // The caller learns that the file is gone, not where the data folder is (R21).
  std::optional<net::ChunkSource> opened;
  try {
    opened = net::ChunkSource::ofFile(path);
  } catch (const FarmError& e) {
    spdlog::error("{}", e.what());
    return grpc::Status(grpc::StatusCode::DATA_LOSS, "the stored file is missing or unreadable on the coordinator");
  }
  const net::ChunkSource& src = *opened;
  const bool sent = net::sendChunks<Msg>(src, offset, *writer, [&](Msg& m, uint64_t at, bool) {
    m.set_offset(at);
    m.set_total_size(src.size());
    fill(m);
  });
  return sent ? grpc::Status::OK : grpc::Status(grpc::StatusCode::CANCELLED, "the caller went away");
}

}  // namespace

// --- Farm -------------------------------------------------------------------------------

grpc::Status FarmService::GetUploadStatus(grpc::ServerContext* ctx, const pb::SceneRef* req, pb::UploadStatus* out) {
  return guarded(ctx, gate_, Role::Client, "GetUploadStatus", [&] {
    *out = c_.scenes().uploadStatus(req->scene_hash());
    return grpc::Status::OK;
  });
}

grpc::Status FarmService::UploadScene(grpc::ServerContext* ctx, grpc::ServerReader<pb::UploadSceneChunk>* reader,
                                      pb::UploadSceneReply* out) {
  return guarded(ctx, gate_, Role::Client, "UploadScene", [&](const Access& access) {
    pb::UploadSceneChunk chunk;
    if (!reader->Read(&chunk)) return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "empty upload stream");
    const std::string hash = chunk.scene_hash();
    c_.scenes().beginUpload(chunk, access);
    // The coordinator checked the size and the resume offset; the stream must continue them.
    net::ChunkReceiver receiver(chunk.offset(), chunk.total_size(), ErrorKind::InvalidArgument, "the upload");
    bool first = true;
    do {
      if (!chunk.scene_hash().empty() && chunk.scene_hash() != hash)
        return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "one upload stream carries one scene");
      const uint64_t at = receiver.accept(first ? std::optional<uint64_t>(chunk.total_size()) : std::nullopt,
                                          chunk.offset(), chunk.data().size());
      first = false;
      if (!chunk.data().empty()) c_.scenes().appendUpload(hash, at, chunk.data());
    } while (reader->Read(&chunk));
    *out = c_.scenes().endUpload(hash);
    return grpc::Status::OK;
  });
}

grpc::Status FarmService::SubmitBake(grpc::ServerContext* ctx, const pb::SubmitBakeRequest* req, pb::JobStatus* out) {
  return guarded(ctx, gate_, Role::Client, "SubmitBake", [&](const Access& access) {
    // Keyframe jobs are named by the tracks that need them: a client taking such a name
    // could stall another's track.
    if (req->request_id().rfind(kKeyframeRequestPrefix, 0) == 0)
      throw FarmError(ErrorKind::InvalidArgument,
                      std::string("request ids starting with '") + kKeyframeRequestPrefix + "' are the farm's own");
    *out = c_.jobs().submit(req->request_id(), net::modelOf(req->spec()), access);
    return grpc::Status::OK;
  });
}

std::shared_ptr<void> FarmService::streamSlot(const char* kind) {
  if (openStreams_.fetch_add(1) >= c_.config().maxWatches) {
    --openStreams_;
    throw FarmError(ErrorKind::ResourceExhausted, std::to_string(c_.config().maxWatches) +
                                                      " watches and subscriptions are open on this coordinator; try "
                                                      "again later");
  }
  c_.metrics().streamsOpen(kind, +1);
  return std::shared_ptr<void>(nullptr, [this, kind](void*) {
    c_.metrics().streamsOpen(kind, -1);
    --openStreams_;
  });
}

grpc::Status FarmService::WatchJob(grpc::ServerContext* ctx, const pb::JobRef* req,
                                   grpc::ServerWriter<pb::JobStatus>* writer) {
  return guarded(ctx, gate_, Role::Client, "WatchJob", [&](const Access& access) {
    c_.jobs().status(req->job_id(), access);  // another client's job is not followed
    const auto slot = streamSlot("watch");
    uint64_t seen = c_.waitForChange(~uint64_t(0), 0);
    for (;;) {
      // A message on every change, and at least once a second (elapsed time and ETA move,
      // and the caller learns the stream is alive).
      pb::JobStatus s = c_.jobs().status(req->job_id());
      if (!writer->Write(s)) return grpc::Status(grpc::StatusCode::CANCELLED, "the caller went away");
      if (s.state() == pb::JOB_DONE || s.state() == pb::JOB_FAILED || s.state() == pb::JOB_CANCELLED)
        return grpc::Status::OK;
      if (ctx->IsCancelled()) return grpc::Status(grpc::StatusCode::CANCELLED, "cancelled by the caller");
      seen = c_.waitForChange(seen, 1000);
    }
  });
}

grpc::Status FarmService::CancelJob(grpc::ServerContext* ctx, const pb::JobRef* req, pb::JobStatus* out) {
  return guarded(ctx, gate_, Role::Client, "CancelJob", [&](const Access& access) {
    *out = c_.jobs().cancel(req->job_id(), access);
    return grpc::Status::OK;
  });
}

grpc::Status FarmService::ListJobs(grpc::ServerContext* ctx, const pb::ListJobsRequest* req, pb::ListJobsReply* out) {
  return guarded(ctx, gate_, Role::Client, "ListJobs", [&](const Access& access) {
    JobService::Page page = c_.jobs().list(req->include_finished(), req->page_size(), req->page_token(), access);
    for (auto& s : page.jobs) *out->add_jobs() = std::move(s);
    out->set_next_page_token(page.nextPageToken);
    return grpc::Status::OK;
  });
}

grpc::Status FarmService::DownloadArtifact(grpc::ServerContext* ctx, const pb::DownloadRequest* req,
                                           grpc::ServerWriter<pb::ArtifactChunk>* writer) {
  return guarded(ctx, gate_, Role::Client, "DownloadArtifact", [&](const Access& access) {
    std::string checksum;
    std::string path = c_.jobs().artifactPath(req->job_id(), &checksum, access);
    return streamFile(path, req->offset(), writer, [&](pb::ArtifactChunk& m) { m.set_checksum(checksum); });
  });
}

grpc::Status FarmService::CreateTrack(grpc::ServerContext* ctx, const pb::CreateTrackRequest* req, pb::TrackStatus* out) {
  return guarded(ctx, gate_, Role::Client, "CreateTrack", [&](const Access& access) {
    *out = c_.tracks().create(*req, access);
    return grpc::Status::OK;
  });
}

grpc::Status FarmService::ListTracks(grpc::ServerContext* ctx, const pb::ListJobsRequest* req, pb::ListTracksReply* out) {
  return guarded(ctx, gate_, Role::Client, "ListTracks", [&](const Access& access) {
    for (auto& t : c_.tracks().list(req->include_finished(), access)) *out->add_tracks() = std::move(t);
    return grpc::Status::OK;
  });
}

grpc::Status FarmService::CancelTrack(grpc::ServerContext* ctx, const pb::TrackRef* req, pb::TrackStatus* out) {
  return guarded(ctx, gate_, Role::Client, "CancelTrack", [&](const Access& access) {
    *out = c_.tracks().cancel(req->track_id(), access);
    return grpc::Status::OK;
  });
}

grpc::Status FarmService::Subscribe(grpc::ServerContext* ctx, const pb::SubscribeRequest* req,
                                    grpc::ServerWriter<pb::VersionChunk>* writer) {
  return guarded(ctx, gate_, Role::Client, "Subscribe", [&](const Access& access) {
    const auto slot = streamSlot("subscribe");
    const std::string& id = req->track_id();
    const pb::TrackStatus first = c_.tracks().status(id, access);  // NOT_FOUND, or another client's
    if (req->after_sequence() > first.latest_sequence())
      throw FarmError(ErrorKind::OutOfRange, "after_sequence " + std::to_string(req->after_sequence()) +
                                                 " is ahead of the track's latest version (" +
                                                 std::to_string(first.latest_sequence()) + ")");
    uint64_t after = req->after_sequence(), seen = 0;
    while (!ctx->IsCancelled()) {
      if (auto v = c_.tracks().versionAfter(id, after)) {
        // One version at a time from the store: the stream holds one chunk, never a queue;
        // a subscriber slower than the retention skips to the oldest version kept.
        pb::TrackVersion info;
        info.set_track_id(id);
        info.set_sequence(v->sequence);
        info.set_keyframe(v->keyframe);
        info.set_instant_unix_ms(v->instantMs);
        *info.mutable_sun_direction() = net::toProto(v->direction);
        info.set_job_id(v->jobId);
        info.set_checksum(v->checksum);
        info.set_file_bytes(v->fileBytes);
        std::string checksum;
        const std::string path = c_.jobs().artifactPath(v->jobId, &checksum);
        std::optional<net::ChunkSource> opened;
        try {
          opened = net::ChunkSource::ofFile(path);
        } catch (const FarmError& e) {
          spdlog::error("{}", e.what());
          return grpc::Status(grpc::StatusCode::DATA_LOSS, "a version's artifact is missing or unreadable on the coordinator");
        }
        const net::ChunkSource& src = *opened;
        const bool sent = net::sendChunks<pb::VersionChunk>(src, 0, *writer, [&](pb::VersionChunk& m, uint64_t at, bool head) {
          if (head) *m.mutable_version() = info;
          m.set_offset(at);
          m.set_total_size(src.size());
          m.set_last(at + std::min<uint64_t>(net::kChunkBytes, src.size() - at) == src.size());
        });
        if (!sent) return grpc::Status(grpc::StatusCode::CANCELLED, "the subscriber went away");
        after = v->sequence;
        continue;
      }
      // An ended track publishes nothing more: done once what it published is sent (looked
      // at again, in case the last version came with the end).
      if (c_.tracks().status(id).state() != pb::TRACK_ACTIVE) {
        if (!c_.tracks().versionAfter(id, after)) return grpc::Status::OK;
        continue;
      }
      seen = c_.waitForChange(seen, 1000);
    }
    return grpc::Status(grpc::StatusCode::CANCELLED, "the subscriber went away");
  });
}

// --- Workers ----------------------------------------------------------------------------

grpc::Status WorkerService::LeaseTile(grpc::ServerContext* ctx, const pb::LeaseRequest* req, pb::TileLease* out) {
  return guarded(ctx, gate_, Role::Worker, "LeaseTile", [&] {
    *out = c_.leases().lease(req->worker_id());
    return grpc::Status::OK;
  });
}

grpc::Status WorkerService::RenewLease(grpc::ServerContext* ctx, const pb::RenewRequest* req, pb::RenewReply* out) {
  return guarded(ctx, gate_, Role::Worker, "RenewLease", [&] {
    *out = c_.leases().renew(req->lease_id());
    return grpc::Status::OK;
  });
}

grpc::Status WorkerService::FetchScene(grpc::ServerContext* ctx, const pb::FetchSceneRequest* req,
                                       grpc::ServerWriter<pb::SceneChunk>* writer) {
  return guarded(ctx, gate_, Role::Worker, "FetchScene", [&] {
    std::string fileName;
    std::string path = c_.scenes().scenePath(req->scene_hash(), &fileName);
    return streamFile(path, req->offset(), writer, [&](pb::SceneChunk& m) { m.set_file_name(fileName); });
  });
}

grpc::Status WorkerService::CompleteTile(grpc::ServerContext* ctx, grpc::ServerReader<pb::TileResultChunk>* reader,
                                         pb::CompleteReply* out) {
  return guarded(ctx, gate_, Role::Worker, "CompleteTile", [&] {
    pb::TileResultChunk chunk;
    if (!reader->Read(&chunk)) return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "empty result stream");
    const std::string leaseId = chunk.lease_id();
    c_.leases().checkResultLease(leaseId);  // before reading the rest of the stream
    const uint64_t total = chunk.total_size();
    const std::string checksum = chunk.checksum();
    if (total == 0) return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "result size 0 is out of range");
    const bool reused = chunk.reused();
    std::map<std::string, double> stages;
    for (const auto& s : chunk.stages()) {
      if (!(s.seconds() >= 0 && s.seconds() < 1e7))
        return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "invalid stage time");
      // Only the stages the pipeline has: each becomes a stored row of the job (R16).
      if (!isStageName(s.stage()))
        return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                            "unknown stage '" + validUtf8Prefix(s.stage(), 32) + "' (stages: " + stageList() + ")");
      stages[s.stage()] += s.seconds();
    }
    net::ChunkReceiver receiver(0, kMaxTileResultBytes, ErrorKind::InvalidArgument, "the result");
    std::string data;
    bool first = true;
    do {
      receiver.accept(first ? std::optional<uint64_t>(total) : std::nullopt, std::nullopt, chunk.data().size());
      first = false;
      data += chunk.data();
    } while (reader->Read(&chunk));
    if (receiver.received() != total)
      return grpc::Status(grpc::StatusCode::DATA_LOSS, "result truncated: " + std::to_string(data.size()) + " of " +
                                                           std::to_string(total) + " bytes");
    if (contentHash(data.data(), data.size()).hex() != checksum)
      return grpc::Status(grpc::StatusCode::DATA_LOSS, "result does not match its checksum");
    out->set_accepted(c_.leases().completeTile(leaseId, data, stages, reused));
    return grpc::Status::OK;
  });
}

grpc::Status WorkerService::FailTile(grpc::ServerContext* ctx, const pb::FailRequest* req, pb::FailReply*) {
  return guarded(ctx, gate_, Role::Worker, "FailTile", [&] {
    // Stored in JobStatus.error, a proto3 string: it must stay valid UTF-8 when cut.
    c_.leases().failTile(req->lease_id(), validUtf8Prefix(req->reason(), 1000), req->kind());
    return grpc::Status::OK;
  });
}

}  // namespace cpvs::server
