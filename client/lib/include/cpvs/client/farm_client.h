// The client's side of the bake farm, as a library: upload a scene, submit a bake,
// watch, cancel, list and download. Its header names no transport type (no gRPC status,
// channel or stub: those live in src/ over net/), so a runtime or a tool links it without
// seeing gRPC or protobuf; jobs and tracks are the farm model's plain values
// (cpvs/net/farm_model.h). The command line's farm subcommands (client/cli/farm_commands.cpp)
// print and choose exit statuses.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "cpvs/net/connection.h"
#include "cpvs/net/error_kind.h"
#include "cpvs/net/farm_model.h"

namespace cpvs::client {

using net::BakeSpec;
using net::isFinalState;
using net::JobOptions;
using net::JobState;
using net::JobStatus;
using net::TrackSpec;
using net::TrackStatus;
using net::TrackVersion;

/// A call to the coordinator that failed, with the kind of error it failed with. what()
/// names the kind as the status code it travelled as, e.g. "NOT_FOUND: no job 42".
class FarmCallError : public std::runtime_error {
 public:
  explicit FarmCallError(const net::FarmError& error) : std::runtime_error(error.what()), kind_(error.kind) {}

  net::ErrorKind kind() const { return kind_; }

  /// True when the request itself was refused and the caller can fix it (invalid
  /// argument, not found, already exists, out of range, unauthenticated, permission
  /// denied, failed precondition, resource exhausted); false when the farm could not be
  /// reached or failed (unavailable, deadline exceeded, data loss, internal, ...).
  bool callerCanFix() const;

 private:
  net::ErrorKind kind_;
};

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
  ~FarmClient();
  FarmClient(const FarmClient&) = delete;
  FarmClient& operator=(const FarmClient&) = delete;

  struct UploadResult {
    std::string sceneHash;   // XXH3-128 of the file, 32 hex digits: BakeSpec::sceneHash
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
  JobStatus submit(const std::string& requestId, const BakeSpec& spec);

  /// Follows a job until it reaches a final state, calling `onUpdate` with every status
  /// the server sends (on each change, and about once a second), and returns the final
  /// one. Throws FarmCallError when the stream breaks before that.
  JobStatus watch(const std::string& jobId, const std::function<void(const JobStatus&)>& onUpdate = {});

  /// Asks the server to cancel a job and returns its status afterwards.
  JobStatus cancel(const std::string& jobId);

  /// The jobs on the server; finished ones too when `includeFinished`.
  std::vector<JobStatus> list(bool includeFinished);

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

  /// Creates a sun track (idempotent by request id, as submit).
  TrackStatus createTrack(const std::string& requestId, const TrackSpec& spec);
  std::vector<TrackStatus> listTracks(bool includeEnded);
  TrackStatus cancelTrack(const std::string& trackId);
  /// Follows a track from after `afterSequence` (0: the oldest version kept): calls
  /// `onVersion` with each version and its whole artifact, checked against its checksum,
  /// in order, as they are published; returns the last sequence received when the track
  /// ends or `onVersion` returns false. Resume after a failure with that sequence: no
  /// version is lost or repeated. FarmCallError when the call fails.
  uint64_t subscribe(const std::string& trackId, uint64_t afterSequence,
                     const std::function<bool(const TrackVersion&, const std::vector<uint8_t>&)>& onVersion);

 private:
  struct Transport;  // channel, stub and the streams over them (src/farm_client.cpp)
  std::unique_ptr<Transport> transport_;
};

}  // namespace cpvs::client
