// Scenes on the coordinator: resumable uploads checked by content hash, imported once
// when complete, and the stored files workers fetch.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <condition_variable>
#include <map>
#include <set>
#include <mutex>
#include <string>
#include <vector>

#include "coordinator/access.h"
#include "cpvs/scene/isolated_import.h"
#include "cpvs/scene/scene.h"
#include "cpvs/v1/farm.pb.h"
#include "store/farm_store.h"

namespace cpvs::server {

namespace pb = ::cpvs::v1;

/// What one client's scenes may take on the coordinator (R15); administrators and the
/// callers of a farm without tokens are not counted.
struct ClientUploadQuota {
  uint64_t uploadingBytes = uint64_t(8) << 30;  // announced by its uploads in progress
  uint64_t storedBytes = uint64_t(32) << 30;    // of the complete scenes it uploaded first
};

class SceneStore {
 public:
  /// Creates scenes/ under the data folder. Uploads are imported under `limits` (in a
  /// child process when it names a helper), at most `maxConcurrentImports` at once.
  SceneStore(FarmStore& store, const std::string& dataDir, uint64_t maxUploadBytes, ImportLimits limits = {},
             int maxConcurrentImports = 2, size_t maxPendingUploads = 64, ClientUploadQuota clientQuota = {});

  pb::UploadStatus uploadStatus(const std::string& sceneHash);
  /// Starts or resumes an upload; its offset must equal the bytes already received. A new
  /// upload counts against its caller's ClientUploadQuota (RESOURCE_EXHAUSTED past it).
  void beginUpload(const pb::UploadSceneChunk& first, const Access& access = Access::all());
  /// Appends data at `offset` (the bytes received so far).
  void appendUpload(const std::string& sceneHash, uint64_t offset, const std::string& data);
  /// Completes the upload when every byte is in: checks the hash, imports the scene
  /// (isolated, see cpvs/scene/isolated_import.h) and keeps its mesh. Other uploads go on meanwhile;
  /// a second caller for the same scene waits for this import.
  pb::UploadSceneReply endUpload(const std::string& sceneHash);
  /// The stored file of a complete scene; FarmError(NotFound) otherwise.
  std::string scenePath(const std::string& sceneHash, std::string* fileName = nullptr);
  /// Whether the stored file of a complete scene still hashes to its name. A damaged or
  /// missing one is removed and the scene marked not uploaded, so that the next submit
  /// uploads it again (R4); false for a scene not stored.
  bool verifyStored(const std::string& sceneHash);
  /// The imported geometry of a complete scene: its mesh as kept at upload (imported
  /// again, isolated, only when that mesh is missing or damaged).
  Scene load(const std::string& sceneHash, SceneStats* stats = nullptr);
  /// Drops the uploads in progress that received no byte for `maxIdle` (by their part
  /// file's time, which outlives a restart); returns how many (R15).
  size_t expireIdleUploads(std::chrono::seconds maxIdle);
  /// Forgets the stored scenes no job or active track names that no submit used since
  /// `beforeMs` (Unix ms), with their files; returns how many (R25).
  size_t pruneUnused(int64_t beforeMs);
  /// Removes the files of scenes the store does not hold (a prune or a dropped upload cut
  /// short by a crash); returns how many. At start, before any upload.
  size_t removeOrphanFiles();

 private:
  std::string partPath(const std::string& hash) const;
  std::string meshPath(const std::string& hash) const;
  /// FarmError(ResourceExhausted) unless `owner` may begin an upload of `totalSize` bytes.
  void checkClientQuota(const std::string& owner, uint64_t totalSize);
  /// Notes that an upload made progress now (under mutex_).
  void touch(const std::string& hash);
  /// Forgets an upload in progress: its files and its row (under mutex_).
  void dropUpload(const std::string& hash);
  /// The files a scene has in the scenes folder (HASH.part, HASH.EXT, HASH.mesh).
  std::vector<std::filesystem::path> uploadFiles(const std::string& hash) const;

  FarmStore& store_;
  std::string folder_;
  uint64_t maxUploadBytes_;
  ImportLimits limits_;
  int maxConcurrentImports_;
  size_t maxPendingUploads_;
  ClientUploadQuota clientQuota_;
  std::mutex mutex_;  // one upload step at a time (imports run without it)
  std::condition_variable importDone_;
  std::set<std::string> importing_;
  int activeImports_ = 0;
  // When each upload in progress last moved, for R19's takeover rule.
  std::map<std::string, std::chrono::steady_clock::time_point> lastActivity_;
  // Uploads in progress found with no file yet, and since when (for their expiry).
  std::map<std::string, std::chrono::steady_clock::time_point> withoutFilesSince_;
};

/// An upload idle this long may be taken over by an announcement of another size or format.
constexpr std::chrono::seconds kUploadIdleTakeover{120};

/// FarmError(InvalidArgument) unless `hash` is 32 lower-case hex digits.
void checkHashText(const std::string& hash, const char* what);

}  // namespace cpvs::server
