#include "cpvs/client/farm_client.h"

#include <grpcpp/grpcpp.h>

#include "cpvs/v1/farm.grpc.pb.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <mutex>
#include <condition_variable>
#include <atomic>
#include <chrono>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <optional>
#include <random>
#include <thread>

#include "cpvs/base/error.h"
#include "cpvs/base/file.h"
#include "cpvs/base/hash.h"
#include "cpvs/net/channel.h"
#include "cpvs/net/chunked_stream.h"
#include "cpvs/net/model_convert.h"
#include "cpvs/net/status.h"

namespace cpvs::client {

namespace pb = ::cpvs::v1;

namespace {

/// Deadline of the unary calls. Streams (uploads, watches, downloads) take as long as
/// their data or the job takes, and have none.
constexpr double kCallSeconds = 60;

/// Size of the file at `path`, 0 when there is none.
uint64_t fileSizeOrZero(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 ? uint64_t(st.st_size) : 0;
}

void check(const grpc::Status& s) {
  if (!s.ok()) throw FarmCallError(net::fromGrpcStatus(s));
}

/// A failure found on this side, named as the status code it stands for.
FarmCallError callError(net::ErrorKind kind, const std::string& message) {
  return FarmCallError(net::FarmError(kind, std::string(net::errorKindName(kind)) + ": " + message));
}

/// An answer of the coordinator as the model's value; one this client cannot read (a
/// newer coordinator's enum value) is the coordinator's failure, not the caller's input.
template <class Message>
auto modelOf(const Message& m) {
  try {
    return net::modelOf(m);
  } catch (const InputError& e) {
    throw callError(net::ErrorKind::Internal, std::string("the coordinator's answer: ") + e.what());
  }
}

}  // namespace

// --- FarmCallError ----------------------------------------------------------------------

bool FarmCallError::callerCanFix() const {
  using net::ErrorKind;
  switch (kind_) {
    case ErrorKind::InvalidArgument:
    case ErrorKind::NotFound:
    case ErrorKind::AlreadyExists:
    case ErrorKind::OutOfRange:
    case ErrorKind::Unauthenticated:
    case ErrorKind::PermissionDenied:
    case ErrorKind::FailedPrecondition:
    case ErrorKind::ResourceExhausted: return true;
    default: return false;
  }
}


std::string randomRequestId() {
  std::random_device rd;
  auto word = [&] { return uint64_t(rd()) << 32 | uint64_t(rd()); };
  Hash128 id{word(), word()};
  return id.hex();
}

// --- FarmClient -------------------------------------------------------------------------

struct FarmClient::Transport {
  explicit Transport(net::Connection c)
      : connection(std::move(c)), channel(net::makeChannel(connection)), stub(pb::Farm::NewStub(channel)) {}

  /// One upload stream starting at `offset`; returns the server's reply.
  pb::UploadSceneReply sendScene(const std::vector<uint8_t>& bytes, const std::string& hash,
                                 const std::string& fileName, uint64_t offset);
  /// One download stream appending to `part`, which holds `offset` bytes; returns the
  /// announced total size and checksum.
  void receiveArtifact(const std::string& jobId, const std::string& part, uint64_t offset, uint64_t& total,
                       std::string& checksum);
  /// One unary call with the token and the unary deadline; FarmCallError when it fails.
  template <class Request, class Reply>
  Reply unary(grpc::Status (pb::Farm::Stub::*call)(grpc::ClientContext*, const Request&, Reply*),
              const Request& request) {
    Reply reply;
    grpc::ClientContext ctx;
    net::prepare(ctx, connection, kCallSeconds);
    check((stub.get()->*call)(&ctx, request, &reply));
    return reply;
  }

  /// A new channel, on new connections: after a stream went silent, the connection under
  /// it may be dead without gRPC knowing yet (a silent partition), and every call on it
  /// would wait for the keepalive to find out.
  void renewChannel() {
    channel = net::makeChannel(connection);
    stub = pb::Farm::NewStub(channel);
  }

  net::Connection connection;
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<pb::Farm::Stub> stub;
};

FarmClient::FarmClient(net::Connection connection) : transport_(std::make_unique<Transport>(std::move(connection))) {}

FarmClient::~FarmClient() = default;

FarmClient::UploadResult FarmClient::uploadScene(const std::string& path) {
  std::vector<uint8_t> bytes = readFile(path);
  if (bytes.empty()) throw InputError("the scene file " + path + " is empty");
  UploadResult result;
  result.sceneHash = contentHash(bytes.data(), bytes.size()).hex();
  const std::string fileName = std::filesystem::path(path).filename().string();

  pb::SceneRef ref;
  ref.set_scene_hash(result.sceneHash);
  const pb::UploadStatus status = transport_->unary(&pb::Farm::Stub::GetUploadStatus, ref);
  if (status.complete()) {
    result.alreadyThere = true;
    return result;
  }
  // Resume an interrupted upload of the same bytes; anything inconsistent starts over.
  uint64_t offset = 0;
  if (status.known() && status.total_size() == bytes.size() && status.received() <= bytes.size())
    offset = status.received();
  const uint64_t firstOffset = offset;
  pb::UploadSceneReply reply;
  // Another client uploading the same file moves the offset on meanwhile (both send the
  // same bytes): carry on from where the server is, until one of the two completes it.
  for (int attempt = 0;; ++attempt) {
    try {
      reply = transport_->sendScene(bytes, result.sceneHash, fileName, offset);
      break;
    } catch (const FarmCallError& e) {
      if (e.kind() != net::ErrorKind::FailedPrecondition || attempt >= 20) throw;
      const pb::UploadStatus now = transport_->unary(&pb::Farm::Stub::GetUploadStatus, ref);
      if (now.complete()) {
        result.alreadyThere = true;
        return result;
      }
      // A different announcement still in progress (another size or format): not ours.
      if (now.known() && now.total_size() != bytes.size()) throw;
      offset = now.known() && now.received() <= bytes.size() ? now.received() : 0;
      std::this_thread::sleep_for(std::chrono::milliseconds(50 * (attempt + 1)));
    }
  }
  if (!reply.complete())
    throw callError(net::ErrorKind::DataLoss, "the server holds " + std::to_string(reply.received()) + " of " +
                                         std::to_string(bytes.size()) + " bytes of " + fileName +
                                         " after the upload; upload it again");
  result.resumedFrom = firstOffset;
  result.bytesSent = bytes.size() - offset;
  result.triangles = reply.triangles();
  return result;
}

pb::UploadSceneReply FarmClient::Transport::sendScene(const std::vector<uint8_t>& bytes, const std::string& hash,
                                           const std::string& fileName, uint64_t offset) {
  grpc::ClientContext ctx;
  net::prepare(ctx, connection);
  pb::UploadSceneReply reply;
  auto writer = stub->UploadScene(&ctx, &reply);
  // When the server ends the call early, Finish says why.
  net::sendChunks<pb::UploadSceneChunk>(net::ChunkSource::ofBytes(bytes.data(), bytes.size()), offset, *writer,
                                        [&](pb::UploadSceneChunk& chunk, uint64_t at, bool first) {
                                          if (first) {
                                            chunk.set_scene_hash(hash);
                                            chunk.set_file_name(fileName);
                                            chunk.set_total_size(bytes.size());
                                          }
                                          chunk.set_offset(at);
                                        });
  writer->WritesDone();
  check(writer->Finish());
  return reply;
}

JobStatus FarmClient::submit(const std::string& requestId, const BakeSpec& spec) {
  pb::SubmitBakeRequest request;
  request.set_request_id(requestId);
  *request.mutable_spec() = net::toProto(spec);
  return modelOf(transport_->unary(&pb::Farm::Stub::SubmitBake, request));
}

JobStatus FarmClient::watch(const std::string& jobId, const std::function<void(const JobStatus&)>& onUpdate) {
  pb::JobRef ref;
  ref.set_job_id(jobId);
  // The server sends a status at least once a second. A watch that hears nothing for
  // kWatchSilenceSeconds reconnects on a new channel (the old connection may be dead
  // without a word, a silent partition); one that gets no status for kWatchGiveUpSeconds
  // (a coordinator down, a partition) gives up as Unavailable. A coordinator restarted on
  // its folder keeps the job, and the watch carries on (R17).
  using Clock = std::chrono::steady_clock;
  constexpr int kWatchSilenceSeconds = 15, kWatchGiveUpSeconds = 120;
  JobStatus last;
  bool any = false;
  // When a status (or a new connection) was last seen, read by the watchdog thread too.
  auto sinceEpochMs = [] {
    return std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now().time_since_epoch()).count();
  };
  std::atomic<int64_t> lastHeardMs{sinceEpochMs()};
  int backoffMs = 250;
  for (;;) {
    grpc::ClientContext ctx;
    net::prepare(ctx, transport_->connection);
    std::mutex m;
    std::condition_variable cv;
    bool done = false;
    const int64_t openedMs = sinceEpochMs();
    std::atomic<bool> silent{false};
    std::thread watchdog([&] {
      std::unique_lock lock(m);
      while (!cv.wait_for(lock, std::chrono::seconds(1), [&] { return done; }))
        if (sinceEpochMs() - std::max(openedMs, lastHeardMs.load()) > kWatchSilenceSeconds * 1000) {
          silent = true;
          ctx.TryCancel();
        }
    });
    auto reader = transport_->stub->WatchJob(&ctx, ref);
    pb::JobStatus status;
    while (reader->Read(&status)) {
      lastHeardMs = sinceEpochMs();
      backoffMs = 250;
      last = modelOf(status);
      any = true;
      if (onUpdate) onUpdate(last);
    }
    const grpc::Status finished = reader->Finish();
    {
      std::lock_guard lock(m);
      done = true;
    }
    cv.notify_all();
    watchdog.join();
    if (finished.ok() && any && isFinalState(last.state)) return last;
    const bool lost = finished.error_code() == grpc::StatusCode::UNAVAILABLE ||
                      finished.error_code() == grpc::StatusCode::CANCELLED ||
                      finished.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED;
    if (!finished.ok() && !lost) check(finished);
    if (finished.ok())
      throw callError(net::ErrorKind::Internal, "the server ended the watch of job " + jobId + " before the job ended");
    if (sinceEpochMs() - lastHeardMs.load() > kWatchGiveUpSeconds * 1000) check(finished);
    if (silent) transport_->renewChannel();
    std::this_thread::sleep_for(std::chrono::milliseconds(backoffMs));
    backoffMs = std::min(backoffMs * 2, 5000);
  }
}

JobStatus FarmClient::cancel(const std::string& jobId) {
  pb::JobRef ref;
  ref.set_job_id(jobId);
  return modelOf(transport_->unary(&pb::Farm::Stub::CancelJob, ref));
}

std::vector<JobStatus> FarmClient::list(bool includeFinished) {
  // Page by page (the coordinator bounds each reply, R16) until the last one.
  pb::ListJobsRequest request;
  request.set_include_finished(includeFinished);
  request.set_page_size(1000);
  std::vector<JobStatus> out;
  for (;;) {
    const pb::ListJobsReply reply = transport_->unary(&pb::Farm::Stub::ListJobs, request);
    for (const pb::JobStatus& job : reply.jobs()) out.push_back(modelOf(job));
    if (reply.next_page_token().empty()) return out;
    if (reply.next_page_token() == request.page_token() || reply.jobs().empty())
      throw callError(net::ErrorKind::Internal, "the coordinator's job listing does not move on");
    request.set_page_token(reply.next_page_token());
  }
}

TrackStatus FarmClient::createTrack(const std::string& requestId, const TrackSpec& spec) {
  pb::CreateTrackRequest request;
  request.set_request_id(requestId);
  *request.mutable_spec() = net::toProto(spec);
  return modelOf(transport_->unary(&pb::Farm::Stub::CreateTrack, request));
}

std::vector<TrackStatus> FarmClient::listTracks(bool includeEnded) {
  pb::ListJobsRequest request;
  request.set_include_finished(includeEnded);
  const pb::ListTracksReply reply = transport_->unary(&pb::Farm::Stub::ListTracks, request);
  std::vector<TrackStatus> out;
  for (const pb::TrackStatus& track : reply.tracks()) out.push_back(modelOf(track));
  return out;
}

TrackStatus FarmClient::cancelTrack(const std::string& trackId) {
  pb::TrackRef ref;
  ref.set_track_id(trackId);
  return modelOf(transport_->unary(&pb::Farm::Stub::CancelTrack, ref));
}

uint64_t FarmClient::subscribe(const std::string& trackId, uint64_t afterSequence,
                               const std::function<bool(const TrackVersion&, const std::vector<uint8_t>&)>& onVersion) {
  pb::SubscribeRequest request;
  request.set_track_id(trackId);
  request.set_after_sequence(afterSequence);
  grpc::ClientContext ctx;
  net::prepare(ctx, transport_->connection);
  auto reader = transport_->stub->Subscribe(&ctx, request);
  uint64_t last = afterSequence;
  pb::VersionChunk chunk;
  pb::TrackVersion version;
  std::optional<net::ChunkReceiver> receiver;
  std::vector<uint8_t> bytes;
  auto broken = [&](const std::string& why) {
    ctx.TryCancel();
    reader->Finish();
    return callError(net::ErrorKind::DataLoss, "the subscription to track " + trackId + ": " + why);
  };
  while (reader->Read(&chunk)) {
    if (chunk.has_version()) {
      if (receiver) throw broken("a version began before the one before it ended");
      version = chunk.version();
      if (version.sequence() <= last) throw broken("version " + std::to_string(version.sequence()) + " came out of order");
      receiver.emplace(0, UINT64_MAX, net::ErrorKind::DataLoss, "version " + std::to_string(version.sequence()));
      bytes.clear();
    }
    if (!receiver) throw broken("data came before its version");
    try {
      const uint64_t at = receiver->accept(chunk.total_size(), chunk.offset(), chunk.data().size());
      bytes.resize(at + chunk.data().size());
      std::memcpy(bytes.data() + at, chunk.data().data(), chunk.data().size());
      if (chunk.last()) receiver->finish();
    } catch (const net::FarmError& e) {
      throw broken(e.what());
    }
    if (!chunk.last()) continue;
    receiver.reset();
    if (contentHash(bytes.data(), bytes.size()).hex() != version.checksum())
      throw broken("version " + std::to_string(version.sequence()) + " does not match its checksum");
    last = version.sequence();
    if (!onVersion(modelOf(version), bytes)) {
      ctx.TryCancel();
      reader->Finish();
      return last;
    }
  }
  check(reader->Finish());
  return last;
}

void FarmClient::Transport::receiveArtifact(const std::string& jobId, const std::string& part, uint64_t offset, uint64_t& total,
                                 std::string& checksum) {
  pb::DownloadRequest request;
  request.set_job_id(jobId);
  request.set_offset(offset);
  grpc::ClientContext ctx;
  net::prepare(ctx, connection);
  auto reader = stub->DownloadArtifact(&ctx, request);
  // A stream that contradicts itself is the server's fault: end the call and report it.
  net::ChunkReceiver receiver(offset, UINT64_MAX, net::ErrorKind::DataLoss, "the download of job " + jobId);
  // Opened at the first chunk, so that a refused request leaves no empty .part behind.
  std::optional<AppendFile> out;
  pb::ArtifactChunk chunk;
  bool first = true;
  try {
    while (reader->Read(&chunk)) {
      if (first) {
        checksum = chunk.checksum();
        out.emplace(part);
      } else if (chunk.checksum() != checksum) {
        throw net::FarmError(net::ErrorKind::DataLoss, "the download of job " + jobId + " changed its checksum midway");
      }
      first = false;
      receiver.accept(chunk.total_size(), chunk.offset(), chunk.data().size());
      out->write(chunk.data().data(), chunk.data().size());
    }
  } catch (const net::FarmError& e) {
    ctx.TryCancel();
    (void)reader->Finish();
    throw FarmCallError(e);
  }
  grpc::Status status = reader->Finish();
  if (out) out->syncAndClose();
  check(status);
  try {
    receiver.finish();
  } catch (const net::FarmError& e) {
    throw FarmCallError(e);
  }
  total = receiver.total();
}

FarmClient::DownloadResult FarmClient::download(const std::string& jobId, const std::string& outPath) {
  const std::string part = outPath + ".part";
  DownloadResult result;
  result.resumedFrom = fileSizeOrZero(part);
  try {
    transport_->receiveArtifact(jobId, part, result.resumedFrom, result.bytes, result.checksum);
  } catch (const FarmCallError& e) {
    // A .part longer than the artifact belongs to something else: start over.
    if (result.resumedFrom == 0 || e.kind() != net::ErrorKind::OutOfRange) throw;
    if (::unlink(part.c_str()) != 0) throw InputError("cannot remove " + part + ": " + std::strerror(errno));
    result.resumedFrom = 0;
    transport_->receiveArtifact(jobId, part, 0, result.bytes, result.checksum);
  }
  std::vector<uint8_t> bytes = readFile(part);
  std::string got = contentHash(bytes.data(), bytes.size()).hex();
  if (got != result.checksum) {
    ::unlink(part.c_str());
    std::string why = result.resumedFrom > 0 ? " (it resumed an earlier " + part + " of " +
                                                   std::to_string(result.resumedFrom) +
                                                   " bytes, which may belong to another file)"
                                             : "";
    throw InputError("the download of job " + jobId + " to " + outPath + " does not match its checksum: got " + got +
                     ", the server announced " + result.checksum + why + "; removed " + part +
                     ", download again");
  }
  if (::rename(part.c_str(), outPath.c_str()) != 0)
    throw InputError("cannot rename " + part + " to " + outPath + ": " + std::strerror(errno));
  return result;
}

}  // namespace cpvs::client
