// The client's side of the bake farm: upload a scene, submit a bake, watch, cancel, list
// and download, over the generated `cpvs::v1::Farm` stub. No command-line code: the
// subcommands in farm_commands.cpp print and choose exit statuses.
#pragma once

#include <grpcpp/grpcpp.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "cpvs/base/error.h"
#include "cpvs/scene/import.h"
#include "cpvs/v1/farm.grpc.pb.h"
#include "cpvs/net/channel.h"
#include "cpvs/net/status.h"

namespace cpvs::cli {

namespace pb = ::cpvs::v1;

/// A call to the coordinator that failed, with the gRPC status it failed with. what() is
/// net::describe(status), e.g. "NOT_FOUND: no job 42".
class FarmCallError : public std::runtime_error {
 public:
  explicit FarmCallError(grpc::Status status);

  const grpc::Status& status() const { return status_; }

  /// The exit status of the command line: 2 when the request itself was refused and the
  /// caller can fix it (INVALID_ARGUMENT, NOT_FOUND, ALREADY_EXISTS, OUT_OF_RANGE,
  /// UNAUTHENTICATED, PERMISSION_DENIED, FAILED_PRECONDITION, RESOURCE_EXHAUSTED), 4 when
  /// the farm could not be reached or failed (UNAVAILABLE, DEADLINE_EXCEEDED, anything else).
  int exitCode() const;

 private:
  grpc::Status status_;
};

/// True for the states a job never leaves: DONE, FAILED, CANCELLED.
bool isFinalState(pb::JobState s);

/// A fresh request id for SubmitBake: 128 random bits as 32 lower-case hex digits.
std::string randomRequestId();

/// One connection to a coordinator. Every method either returns what the farm answered
/// or throws FarmCallError (the RPC failed), or InputError (a local file cannot be read or
/// written, or a download does not match its checksum). Not thread-safe.
class FarmClient {
 public:
  /// Throws InputError when the CA file of `connection` cannot be read. Connecting is
  /// lazy: an unreachable server shows at the first call, as UNAVAILABLE.
  explicit FarmClient(net::Connection connection);

  struct UploadResult {
    std::string sceneHash;   // XXH3-128 of the file, 32 hex digits: BakeSpec.scene_hash
    bool alreadyThere = false;  // the server held the complete scene; nothing was sent
    uint64_t resumedFrom = 0;   // bytes the server held of an earlier, interrupted upload
    uint64_t bytesSent = 0;
    uint64_t triangles = 0;     // as the server imported it; 0 when alreadyThere
  };

  /// Makes the file at `path` available on the server under its content hash: asks
  /// GetUploadStatus first and returns at once when the scene is complete there; streams
  /// the rest of it otherwise, resuming from the bytes the server already holds. The file
  /// is announced under its base name, whose extension tells the server's importer the
  /// format. Throws FarmCallError when the server refuses the file (it does not import,
  /// it is too large, ...).
  UploadResult uploadScene(const std::string& path);

  /// Submits a bake of an uploaded scene. Submitting again with the same `requestId` and
  /// spec returns the same job; with another spec it fails with ALREADY_EXISTS.
  pb::JobStatus submit(const std::string& requestId, const pb::BakeSpec& spec);

  /// Follows a job until it reaches a final state, calling `onUpdate` with every status
  /// the server sends (on each change, and about once a second), and returns the final
  /// one. Throws FarmCallError when the stream breaks before that.
  pb::JobStatus watch(const std::string& jobId, const std::function<void(const pb::JobStatus&)>& onUpdate = {});

  /// Asks the server to cancel a job and returns its status afterwards.
  pb::JobStatus cancel(const std::string& jobId);

  /// The jobs on the server; finished ones too when `includeFinished`.
  std::vector<pb::JobStatus> list(bool includeFinished);

  struct DownloadResult {
    uint64_t bytes = 0;        // size of the artifact
    uint64_t resumedFrom = 0;  // bytes kept from an earlier, interrupted download
    std::string checksum;      // XXH3-128 of the artifact, 32 hex digits, verified
  };

  /// Downloads the artifact of a finished job to `outPath`. Data goes to `outPath`.part
  /// first; an existing .part is resumed from its size (restarted when it is longer than
  /// the artifact). Every chunk must continue the previous one and announce the same size
  /// and checksum. Once complete, the file's XXH3-128 is checked against the checksum:
  /// on a mismatch the .part is deleted and InputError thrown; otherwise the .part is
  /// flushed to disk and renamed to `outPath`. An interrupted transfer leaves the .part
  /// for the next attempt and throws FarmCallError.
  DownloadResult download(const std::string& jobId, const std::string& outPath);

 private:
  /// One upload stream starting at `offset`; returns the server's reply.
  pb::UploadSceneReply sendScene(const std::vector<uint8_t>& bytes, const std::string& hash,
                                 const std::string& fileName, uint64_t offset);
  /// One download stream appending to `part`, which holds `offset` bytes; returns the
  /// announced total size and checksum.
  void receiveArtifact(const std::string& jobId, const std::string& part, uint64_t offset, uint64_t& total,
                       std::string& checksum);

  net::Connection connection_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<pb::Farm::Stub> stub_;
};

}  // namespace cpvs::cli
