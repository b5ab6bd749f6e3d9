#include "cpvs/base/error.h"
#include "cpvs/scene/import.h"
#include "farm_service.h"

#include <spdlog/spdlog.h>

#include <fstream>

#include "farm_channel.h"
#include "farm_convert.h"

namespace cpvs::server {

namespace {

/// Largest sub-DAG a worker may send (a 4K tile of a dense scene is tens of MB).
constexpr uint64_t kMaxTileResultBytes = uint64_t(2) << 30;

grpc::Status toStatus(const FarmError& e) {
  using grpc::StatusCode;
  StatusCode code = StatusCode::INTERNAL;
  switch (e.kind) {
    case ErrorKind::InvalidArgument: code = StatusCode::INVALID_ARGUMENT; break;
    case ErrorKind::NotFound: code = StatusCode::NOT_FOUND; break;
    case ErrorKind::FailedPrecondition: code = StatusCode::FAILED_PRECONDITION; break;
    case ErrorKind::AlreadyExists: code = StatusCode::ALREADY_EXISTS; break;
    case ErrorKind::ResourceExhausted: code = StatusCode::RESOURCE_EXHAUSTED; break;
    case ErrorKind::DataLoss: code = StatusCode::DATA_LOSS; break;
    case ErrorKind::Internal: code = StatusCode::INTERNAL; break;
  }
  return grpc::Status(code, e.what());
}

/// Checks the caller's bearer token against the role an RPC needs.
grpc::Status authorize(const grpc::ServerContext* ctx, const TokenTable& tokens, Role needed) {
  if (!tokens.enabled()) return grpc::Status::OK;
  const auto& md = ctx->client_metadata();
  auto it = md.find("authorization");
  if (it == md.end()) return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, "no bearer token");
  std::string value(it->second.data(), it->second.size());
  const std::string prefix = "Bearer ";
  if (value.rfind(prefix, 0) != 0)
    return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, "authorization is not a bearer token");
  auto role = tokens.roleOf(value.substr(prefix.size()));
  if (!role) return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, "unknown token");
  if (!TokenTable::allows(*role, needed))
    return grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                        std::string("a ") + roleName(*role) + " token cannot call this (needs " + roleName(needed) + ")");
  return grpc::Status::OK;
}

/// Runs `body` after authorization, turning every error into a status: the server keeps
/// serving whatever a request holds.
template <class F>
grpc::Status guarded(const grpc::ServerContext* ctx, const TokenTable& tokens, Role needed, const char* rpc, F&& body) {
  grpc::Status auth = authorize(ctx, tokens, needed);
  if (!auth.ok()) return auth;
  try {
    return body();
  } catch (const FarmError& e) {
    if (e.kind == ErrorKind::Internal) spdlog::error("{}: {}", rpc, e.what());
    return toStatus(e);
  } catch (const InputError& e) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, e.what());
  } catch (const std::exception& e) {
    spdlog::error("{}: internal error: {}", rpc, e.what());
    return grpc::Status(grpc::StatusCode::INTERNAL, std::string("internal error: ") + e.what());
  }
}

/// Streams a file from `offset` in chunks; `fill` completes each message.
template <class Msg, class Fill>
grpc::Status streamFile(grpc::ServerContext* ctx, const std::string& path, uint64_t offset,
                        grpc::ServerWriter<Msg>* writer, Fill&& fill) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return grpc::Status(grpc::StatusCode::INTERNAL, "cannot read " + path);
  in.seekg(0, std::ios::end);
  uint64_t size = uint64_t(in.tellg());
  if (offset > size)
    return grpc::Status(grpc::StatusCode::OUT_OF_RANGE,
                        "offset " + std::to_string(offset) + " is past the end (" + std::to_string(size) + " bytes)");
  in.seekg(std::streamoff(offset));
  std::string buf(farm::kChunkBytes, '\0');
  do {
    if (ctx->IsCancelled()) return grpc::Status(grpc::StatusCode::CANCELLED, "cancelled by the caller");
    uint64_t n = std::min<uint64_t>(farm::kChunkBytes, size - offset);
    in.read(buf.data(), std::streamsize(n));
    Msg m;
    m.set_offset(offset);
    m.set_data(buf.data(), n);
    m.set_total_size(size);
    fill(m);
    if (!writer->Write(m)) return grpc::Status(grpc::StatusCode::CANCELLED, "the caller went away");
    offset += n;
  } while (offset < size);
  return grpc::Status::OK;
}

}  // namespace

// --- Farm -------------------------------------------------------------------------------

grpc::Status FarmService::GetUploadStatus(grpc::ServerContext* ctx, const pb::SceneRef* req, pb::UploadStatus* out) {
  return guarded(ctx, tokens_, Role::Client, "GetUploadStatus", [&] {
    *out = c_.uploadStatus(req->scene_hash());
    return grpc::Status::OK;
  });
}

grpc::Status FarmService::UploadScene(grpc::ServerContext* ctx, grpc::ServerReader<pb::UploadSceneChunk>* reader,
                                      pb::UploadSceneReply* out) {
  return guarded(ctx, tokens_, Role::Client, "UploadScene", [&] {
    pb::UploadSceneChunk chunk;
    if (!reader->Read(&chunk)) return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "empty upload stream");
    const std::string hash = chunk.scene_hash();
    c_.beginUpload(chunk);
    uint64_t offset = chunk.offset();
    do {
      if (chunk.data().size() > farm::kChunkBytes)
        return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                            "chunk of " + std::to_string(chunk.data().size()) + " bytes; the limit is " +
                                std::to_string(farm::kChunkBytes));
      if (!chunk.scene_hash().empty() && chunk.scene_hash() != hash)
        return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "one upload stream carries one scene");
      if (chunk.offset() != offset)
        return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                            "chunk at byte " + std::to_string(chunk.offset()) + ", expected " + std::to_string(offset));
      if (!chunk.data().empty()) c_.appendUpload(hash, offset, chunk.data());
      offset += chunk.data().size();
    } while (reader->Read(&chunk));
    *out = c_.endUpload(hash);
    return grpc::Status::OK;
  });
}

grpc::Status FarmService::SubmitBake(grpc::ServerContext* ctx, const pb::SubmitBakeRequest* req, pb::JobStatus* out) {
  return guarded(ctx, tokens_, Role::Client, "SubmitBake", [&] {
    *out = c_.submit(*req);
    return grpc::Status::OK;
  });
}

grpc::Status FarmService::WatchJob(grpc::ServerContext* ctx, const pb::JobRef* req,
                                   grpc::ServerWriter<pb::JobStatus>* writer) {
  return guarded(ctx, tokens_, Role::Client, "WatchJob", [&] {
    uint64_t seen = c_.waitForChange(~uint64_t(0), 0);
    for (;;) {
      // A message on every change, and at least once a second (elapsed time and ETA move,
      // and the caller learns the stream is alive).
      pb::JobStatus s = c_.status(req->job_id());
      if (!writer->Write(s)) return grpc::Status(grpc::StatusCode::CANCELLED, "the caller went away");
      if (s.state() == pb::JOB_DONE || s.state() == pb::JOB_FAILED || s.state() == pb::JOB_CANCELLED)
        return grpc::Status::OK;
      if (ctx->IsCancelled()) return grpc::Status(grpc::StatusCode::CANCELLED, "cancelled by the caller");
      seen = c_.waitForChange(seen, 1000);
    }
  });
}

grpc::Status FarmService::CancelJob(grpc::ServerContext* ctx, const pb::JobRef* req, pb::JobStatus* out) {
  return guarded(ctx, tokens_, Role::Client, "CancelJob", [&] {
    *out = c_.cancel(req->job_id());
    return grpc::Status::OK;
  });
}

grpc::Status FarmService::ListJobs(grpc::ServerContext* ctx, const pb::ListJobsRequest* req, pb::ListJobsReply* out) {
  return guarded(ctx, tokens_, Role::Client, "ListJobs", [&] {
    for (auto& s : c_.list(req->include_finished())) *out->add_jobs() = std::move(s);
    return grpc::Status::OK;
  });
}

grpc::Status FarmService::DownloadArtifact(grpc::ServerContext* ctx, const pb::DownloadRequest* req,
                                           grpc::ServerWriter<pb::ArtifactChunk>* writer) {
  return guarded(ctx, tokens_, Role::Client, "DownloadArtifact", [&] {
    std::string checksum;
    std::string path = c_.artifactPath(req->job_id(), &checksum);
    return streamFile(ctx, path, req->offset(), writer, [&](pb::ArtifactChunk& m) { m.set_checksum(checksum); });
  });
}

// --- Workers ----------------------------------------------------------------------------

grpc::Status WorkerService::LeaseTile(grpc::ServerContext* ctx, const pb::LeaseRequest* req, pb::TileLease* out) {
  return guarded(ctx, tokens_, Role::Worker, "LeaseTile", [&] {
    *out = c_.lease(req->worker_id());
    return grpc::Status::OK;
  });
}

grpc::Status WorkerService::RenewLease(grpc::ServerContext* ctx, const pb::RenewRequest* req, pb::RenewReply* out) {
  return guarded(ctx, tokens_, Role::Worker, "RenewLease", [&] {
    *out = c_.renew(req->lease_id());
    return grpc::Status::OK;
  });
}

grpc::Status WorkerService::FetchScene(grpc::ServerContext* ctx, const pb::FetchSceneRequest* req,
                                       grpc::ServerWriter<pb::SceneChunk>* writer) {
  return guarded(ctx, tokens_, Role::Worker, "FetchScene", [&] {
    std::string fileName;
    std::string path = c_.scenePath(req->scene_hash(), &fileName);
    return streamFile(ctx, path, req->offset(), writer, [&](pb::SceneChunk& m) { m.set_file_name(fileName); });
  });
}

grpc::Status WorkerService::CompleteTile(grpc::ServerContext* ctx, grpc::ServerReader<pb::TileResultChunk>* reader,
                                         pb::CompleteReply* out) {
  return guarded(ctx, tokens_, Role::Worker, "CompleteTile", [&] {
    pb::TileResultChunk chunk;
    if (!reader->Read(&chunk)) return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "empty result stream");
    const std::string leaseId = chunk.lease_id();
    const uint64_t total = chunk.total_size();
    const std::string checksum = chunk.checksum();
    if (total == 0 || total > kMaxTileResultBytes)
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "result size " + std::to_string(total) + " is out of range");
    std::map<std::string, double> stages;
    for (const auto& s : chunk.stages()) {
      if (!(s.seconds() >= 0 && s.seconds() < 1e7) || s.stage().empty() || s.stage().size() > 32)
        return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "invalid stage time");
      stages[s.stage()] += s.seconds();
    }
    std::string data;
    do {
      if (chunk.data().size() > farm::kChunkBytes)
        return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "chunk larger than " + std::to_string(farm::kChunkBytes));
      if (data.size() + chunk.data().size() > total)
        return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "the result runs past its announced size");
      data += chunk.data();
    } while (reader->Read(&chunk));
    if (data.size() != total)
      return grpc::Status(grpc::StatusCode::DATA_LOSS, "result truncated: " + std::to_string(data.size()) + " of " +
                                                           std::to_string(total) + " bytes");
    if (farm::contentHash(data.data(), data.size()).hex() != checksum)
      return grpc::Status(grpc::StatusCode::DATA_LOSS, "result does not match its checksum");
    out->set_accepted(c_.completeTile(leaseId, data, stages));
    return grpc::Status::OK;
  });
}

grpc::Status WorkerService::FailTile(grpc::ServerContext* ctx, const pb::FailRequest* req, pb::FailReply*) {
  return guarded(ctx, tokens_, Role::Worker, "FailTile", [&] {
    c_.failTile(req->lease_id(), req->reason().substr(0, 1000));
    return grpc::Status::OK;
  });
}

}  // namespace cpvs::server
