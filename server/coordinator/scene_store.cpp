#include "coordinator/scene_store.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "cpvs/base/error.h"
#include "cpvs/base/file.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/text.h"
#include "cpvs/net/error_kind.h"
#include "coordinator/failpoint.h"
#include "cpvs/scene/isolated_import.h"
#include "cpvs/scene/mesh_file.h"

namespace cpvs::server {

namespace fs = std::filesystem;
using net::ErrorKind;
using net::FarmError;

namespace {

/// The extension of an uploaded file name, which tells the importer its format: a dot
/// and 1..10 letters or digits. FarmError otherwise.
std::string safeExtension(const std::string& fileName) {
  std::string ext = fs::path(fileName).extension().string();
  bool ok = ext.size() >= 2 && ext.size() <= 11;
  for (size_t i = 1; ok && i < ext.size(); ++i) ok = std::isalnum(static_cast<unsigned char>(ext[i])) != 0;
  if (!ok) throw FarmError(ErrorKind::InvalidArgument, "file name '" + fileName + "' has no usable extension");
  return ext;
}

/// The same upload started over: nothing received, not imported, still its client's.
SceneRecord startedOver(const SceneRecord& r) {
  return SceneRecord{r.hash, r.fileName, "", r.totalSize, 0, 0, false, r.owner};
}

/// Bytes in MiB, for messages.
std::string mib(uint64_t bytes) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f MiB", double(bytes) / (1 << 20));
  return text;
}

}  // namespace

void checkHashText(const std::string& hash, const char* what) {
  try {
    parseHashHex(hash, what);
  } catch (const InputError& e) {
    throw FarmError(ErrorKind::InvalidArgument, e.what());
  }
}

SceneStore::SceneStore(FarmStore& store, const std::string& dataDir, uint64_t maxUploadBytes, ImportLimits limits,
                       int maxConcurrentImports, size_t maxPendingUploads, ClientUploadQuota clientQuota)
    : store_(store),
      folder_((fs::path(dataDir) / "scenes").string()),
      maxUploadBytes_(maxUploadBytes),
      limits_(std::move(limits)),
      maxConcurrentImports_(std::max(1, maxConcurrentImports)),
      maxPendingUploads_(maxPendingUploads),
      clientQuota_(clientQuota) {
  createFolderDurably(folder_);
}

std::string SceneStore::partPath(const std::string& hash) const { return (fs::path(folder_) / (hash + ".part")).string(); }

pb::UploadStatus SceneStore::uploadStatus(const std::string& hash) {
  checkHashText(hash, "scene_hash");
  pb::UploadStatus s;
  s.set_scene_hash(hash);
  if (auto r = store_.scene(hash)) {
    s.set_known(true);
    s.set_received(r->received);
    s.set_total_size(r->totalSize);
    s.set_complete(r->complete);
    if (r->complete) store_.touchScene(hash);  // a client that finds it stored submits next
  }
  return s;
}

void SceneStore::beginUpload(const pb::UploadSceneChunk& first, const Access& access) {
  checkHashText(first.scene_hash(), "scene_hash");
  std::string ext = safeExtension(first.file_name());
  if (first.total_size() == 0) throw FarmError(ErrorKind::InvalidArgument, "the scene file is empty");
  if (first.total_size() > maxUploadBytes_)
    throw FarmError(ErrorKind::ResourceExhausted, "the scene is " + std::to_string(first.total_size()) +
                                                      " bytes; the limit is " + std::to_string(maxUploadBytes_));
  std::lock_guard lock(mutex_);
  auto r = store_.scene(first.scene_hash());
  if (r && r->complete) {  // known: nothing to do but note the use (the submit follows)
    store_.touchScene(r->hash);
    return;
  }
  // The hash names one file: two clients uploading it send the same bytes, and the one
  // that comes second carries on from the first's offset, under the first's file name
  // when only the name differs (R19). Another size or format is a different claim about
  // the file: refused while the upload it would wipe is making progress, taken over once
  // that one has been idle (or the coordinator restarted since).
  const bool anotherClaim = r && (r->totalSize != first.total_size() ||
                                  fs::path(r->fileName).extension() != fs::path(first.file_name()).extension());
  // A new upload is its caller's: within its quota, checked before anything is dropped
  // to make room for it.
  if ((!r || anotherClaim) && !access.everything) checkClientQuota(access.owner, first.total_size());
  if (anotherClaim) {
    const auto last = lastActivity_.find(first.scene_hash());
    if (last != lastActivity_.end() && std::chrono::steady_clock::now() - last->second < kUploadIdleTakeover)
      throw FarmError(ErrorKind::FailedPrecondition,
                      "scene " + r->hash + " is being uploaded by another client as " + std::to_string(r->totalSize) +
                          " bytes of " + safeExtension(r->fileName) + "; a hash names one file");
    fs::remove(partPath(first.scene_hash()));
    r.reset();
  }
  if (!r) {
    // A quota of uploads in progress (R15): past it, the idle ones (no byte for two
    // minutes, or since a restart) are dropped; if none is idle, the new one waits.
    std::vector<std::string> pending = store_.incompleteScenes();
    if (pending.size() >= maxPendingUploads_) {
      const auto now = std::chrono::steady_clock::now();
      for (const std::string& hash : pending) {
        const auto last = lastActivity_.find(hash);
        if (importing_.count(hash) || (last != lastActivity_.end() && now - last->second < kUploadIdleTakeover)) continue;
        dropUpload(hash);
        spdlog::info("upload of scene {} dropped: idle, and {} uploads are waiting", hash, pending.size());
      }
      if (store_.incompleteScenes().size() >= maxPendingUploads_)
        throw FarmError(ErrorKind::ResourceExhausted, std::to_string(maxPendingUploads_) +
                                                          " uploads are in progress on this coordinator; try again later");
    }
  }
  SceneRecord rec =
      r ? *r : SceneRecord{first.scene_hash(), first.file_name(), "", first.total_size(), 0, 0, false, access.owner};
  if (first.offset() != rec.received)
    throw FarmError(ErrorKind::FailedPrecondition, "upload of " + rec.hash + " must resume at byte " +
                                                       std::to_string(rec.received) + ", not " +
                                                       std::to_string(first.offset()));
  store_.putScene(rec);
  touch(rec.hash);
}

void SceneStore::checkClientQuota(const std::string& owner, uint64_t totalSize) {
  // Per client (R15): what its uploads in progress may still write, and what its stored
  // scenes take. A scene another client stored first costs nothing (it is not stored
  // twice), and a stored scene stops counting when retention forgets it.
  const SceneBytes held = store_.sceneBytesOf(owner);
  if (held.uploading + totalSize > clientQuota_.uploadingBytes)
    throw FarmError(ErrorKind::ResourceExhausted,
                    "this client's uploads in progress hold " + mib(held.uploading) + " and this one needs " +
                        mib(totalSize) + "; the limit is " + mib(clientQuota_.uploadingBytes) +
                        " per client: finish those (or let them expire) first");
  // Uploads in progress become stored scenes: counted here too, so that several begun at
  // once cannot together pass the quota.
  if (held.stored + held.uploading + totalSize > clientQuota_.storedBytes)
    throw FarmError(ErrorKind::ResourceExhausted,
                    "this client's stored scenes and uploads take " + mib(held.stored + held.uploading) +
                        " and this one needs " + mib(totalSize) +
                        "; the limit is " + mib(clientQuota_.storedBytes) +
                        " per client: scenes no job names are forgotten after the farm's retention time");
}

void SceneStore::dropUpload(const std::string& hash) {
  store_.deleteScene(hash);
  std::error_code ec;
  for (const fs::path& file : uploadFiles(hash)) fs::remove(file, ec);
  lastActivity_.erase(hash);
  withoutFilesSince_.erase(hash);
}

std::vector<fs::path> SceneStore::uploadFiles(const std::string& hash) const {
  // The part being received, the whole file (renamed into place, perhaps before its
  // import was committed, R5) and its mesh: HASH.part, HASH.EXT, HASH.mesh.
  std::vector<fs::path> out;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder_, ec))
    if (entry.path().filename().string().rfind(hash + ".", 0) == 0) out.push_back(entry.path());
  return out;
}

size_t SceneStore::expireIdleUploads(std::chrono::seconds maxIdle) {
  std::lock_guard lock(mutex_);
  size_t dropped = 0;
  const auto now = fs::file_time_type::clock::now();
  const std::vector<std::string> pending = store_.incompleteScenes();
  std::erase_if(withoutFilesSince_, [&](const auto& entry) {  // uploads completed since
    return std::find(pending.begin(), pending.end(), entry.first) == pending.end();
  });
  for (const std::string& hash : pending) {
    if (importing_.count(hash)) continue;
    const auto last = lastActivity_.find(hash);
    if (last != lastActivity_.end() && std::chrono::steady_clock::now() - last->second < maxIdle) continue;
    // Its files' times outlive a restart; an upload with no file yet is timed from when
    // this coordinator first found it so.
    const std::vector<fs::path> files = uploadFiles(hash);
    bool recent = false;
    for (const fs::path& file : files) {
      std::error_code ec;
      const auto written = fs::last_write_time(file, ec);
      recent = recent || ec || now - written < maxIdle;
    }
    if (files.empty()) {
      const auto seen = withoutFilesSince_.try_emplace(hash, std::chrono::steady_clock::now()).first;
      recent = std::chrono::steady_clock::now() - seen->second < maxIdle;
    }
    if (recent) continue;
    dropUpload(hash);
    ++dropped;
    spdlog::info("upload of scene {} expired: no byte for {} s", hash, maxIdle.count());
  }
  return dropped;
}

size_t SceneStore::removeOrphanFiles() {
  // The row goes before the files (a prune, a dropped upload): a crash between the two
  // leaves files no row names.
  std::lock_guard lock(mutex_);
  size_t removed = 0;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder_, ec)) {
    const std::string name = entry.path().filename().string();
    const std::string hash = name.substr(0, name.find('.'));
    if (hash.size() != 32 || name.find(".tmp.") != std::string::npos || store_.scene(hash)) continue;
    std::error_code gone;
    if (fs::remove(entry.path(), gone)) ++removed;
  }
  return removed;
}

size_t SceneStore::pruneUnused(int64_t beforeMs) {
  // Under the upload lock: no upload of the same hash starts while its files go.
  std::lock_guard lock(mutex_);
  size_t pruned = 0;
  for (;;) {
    const std::vector<std::string> hashes = store_.pruneUnusedScenes(beforeMs, 256);
    for (const std::string& hash : hashes) {
      std::error_code ec;
      for (const fs::path& file : uploadFiles(hash)) fs::remove(file, ec);
    }
    pruned += hashes.size();
    if (hashes.size() < 256) return pruned;
  }
}

void SceneStore::touch(const std::string& hash) {
  // Bounded by the uploads in progress; entries of finished uploads are dropped as they end.
  if (lastActivity_.size() >= 4096) lastActivity_.clear();
  lastActivity_[hash] = std::chrono::steady_clock::now();
}

void SceneStore::appendUpload(const std::string& hash, uint64_t offset, const std::string& data) {
  std::lock_guard lock(mutex_);
  auto r = store_.scene(hash);
  if (!r) throw FarmError(ErrorKind::NotFound, "no upload of scene " + hash + " was started");
  if (r->complete) return;
  // Another client's upload of the same file moved on meanwhile: resume where it is.
  if (offset != r->received)
    throw FarmError(ErrorKind::FailedPrecondition, "chunk at byte " + std::to_string(offset) + ", expected " +
                                                       std::to_string(r->received));
  if (r->received + data.size() > r->totalSize)
    throw FarmError(ErrorKind::InvalidArgument, "the upload runs past its announced size of " +
                                                    std::to_string(r->totalSize) + " bytes");
  // At the acknowledged offset, not the file's end: bytes written before a crash but
  // never acknowledged are cut off. Synced before `received` is committed, so that an
  // acknowledged byte survives a power cut.
  try {
    replaceTail(partPath(hash), r->received, data.data(), data.size());
  } catch (const InputError& e) {
    spdlog::error("{}", e.what());  // the path stays in the log, not in the caller's message
    // The coordinator's disk (full): the client may send the same bytes again later (R9).
    throw FarmError(ErrorKind::Unavailable, "the coordinator cannot store the upload now (its disk); try again");
  }
  r->received += data.size();
  store_.putScene(*r);
  touch(hash);
}

pb::UploadSceneReply SceneStore::endUpload(const std::string& hash) {
  std::unique_lock lock(mutex_);
  // A second client finishing the same upload waits for the first one's import.
  importDone_.wait(lock, [&] { return !importing_.count(hash); });
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
  const fs::path part = partPath(hash);
  const fs::path final = fs::path(folder_) / (hash + safeExtension(r->fileName));
  // Every byte arrived; a crash may have come after the rename to `final` or during the
  // import (R5): then the stored file is checked and imported again. Lost both ways, the
  // upload starts over.
  auto restart = [&] { store_.putScene(startedOver(*r)); };
  std::error_code ec;
  const bool renamed = !fs::exists(part, ec) && fs::exists(final, ec);
  if (!renamed && !fs::exists(part, ec)) {
    restart();
    throw FarmError(ErrorKind::DataLoss, "the bytes of scene " + hash + " were lost before they were stored; upload again");
  }
  const fs::path stored = renamed ? final : part;
  std::vector<uint8_t> bytes = readFile(stored.string());
  std::string got = contentHash(bytes.data(), bytes.size()).hex();
  if (got != hash) {
    fs::remove(stored);
    restart();
    throw FarmError(ErrorKind::DataLoss, "the uploaded bytes hash to " + got + ", not " + hash + "; upload again");
  }
  bytes = {};
  if (!renamed) {
    fs::rename(part, final);
    syncParentFolder(final.string());
  }
  failpoint("upload-renamed");
  // The import runs without the lock, so that other uploads go on meanwhile (R6), and at
  // most maxConcurrentImports at once.
  importing_.insert(hash);
  importDone_.wait(lock, [&] { return activeImports_ < maxConcurrentImports_; });
  ++activeImports_;
  lock.unlock();
  SceneStats stats;
  std::string failure;
  ErrorKind failureKind = ErrorKind::InvalidArgument;
  try {
    std::vector<uint8_t> mesh;
    const Scene scene = importIsolated(final.string(), limits_, &stats, &mesh);
    writeFileAtomic(meshPath(hash), mesh);
    r->triangles = stats.triangles;
    r->geometryHash = sceneHash(scene).hex();
  } catch (const InputError& e) {
    // The importer names the stored file: the caller is told its own file name instead,
    // not where the data folder is.
    std::string why = e.what();
    const std::string storedName = final.string();
    for (size_t at = why.find(storedName); at != std::string::npos; at = why.find(storedName, at + r->fileName.size()))
      why.replace(at, storedName.size(), r->fileName);
    failure = "the scene does not import: " + why;
  } catch (const std::exception& e) {
    // Out of memory, a file system error, no importer to run: not the caller's fault.
    spdlog::error("importing scene {} failed: {}", hash, loggable(e.what()));
    failure = "the scene could not be imported on the server; upload it again";
    failureKind = ErrorKind::Internal;
  }
  lock.lock();
  --activeImports_;
  importing_.erase(hash);
  importDone_.notify_all();
  if (!failure.empty()) {
    // The upload is not left half imported.
    fs::remove(final, ec);
    fs::remove(meshPath(hash), ec);
    restart();
    lastActivity_.erase(hash);
    throw FarmError(failureKind, failure);
  }
  r->complete = true;
  store_.putScene(*r);
  lastActivity_.erase(hash);
  spdlog::info("scene {} ({}, {} bytes, {} triangles) stored", hash, loggable(r->fileName), r->totalSize, r->triangles);
  reply.set_complete(true);
  reply.set_triangles(r->triangles);
  return reply;
}

std::string SceneStore::scenePath(const std::string& hash, std::string* fileName) {
  checkHashText(hash, "scene_hash");
  auto r = store_.scene(hash);
  if (!r || !r->complete) throw FarmError(ErrorKind::NotFound, "scene " + hash + " is not on the server");
  if (fileName) *fileName = r->fileName;
  return (fs::path(folder_) / (hash + safeExtension(r->fileName))).string();
}

std::string SceneStore::meshPath(const std::string& hash) const { return (fs::path(folder_) / (hash + ".mesh")).string(); }

bool SceneStore::verifyStored(const std::string& hash) {
  checkHashText(hash, "scene_hash");
  std::lock_guard lock(mutex_);
  auto r = store_.scene(hash);
  if (!r || !r->complete) return false;
  const fs::path stored = fs::path(folder_) / (hash + safeExtension(r->fileName));
  bool intact = false;
  try {
    const std::vector<uint8_t> bytes = readFile(stored.string());
    intact = contentHash(bytes.data(), bytes.size()).hex() == hash;
  } catch (const std::exception&) {
  }
  if (intact) return true;
  spdlog::error("the stored scene {} is missing or fails its hash: forgotten, to be uploaded again", hash);
  std::error_code ec;
  fs::remove(stored, ec);
  fs::remove(partPath(hash), ec);
  fs::remove(meshPath(hash), ec);
  store_.putScene(startedOver(*r));
  return false;
}

Scene SceneStore::load(const std::string& sceneHash, SceneStats* stats) {
  store_.touchScene(sceneHash);  // used now, before it is looked up: no prune takes it from here
  const std::string stored = scenePath(sceneHash);
  // The mesh kept at upload: a submit does not import the file again.
  const std::string mesh = meshPath(sceneHash);
  try {
    const std::vector<uint8_t> bytes = readFile(mesh);
    return decodeSceneMesh(bytes.data(), bytes.size(), "the stored mesh of scene " + sceneHash, stats);
  } catch (const InputError& e) {
    std::error_code ec;
    if (fs::exists(mesh, ec)) spdlog::warn("{}: importing the scene again", e.what());
  }
  // A data folder from before meshes were kept, or a mesh damaged on disk.
  std::vector<uint8_t> bytes;
  Scene scene = importIsolated(stored, limits_, stats, &bytes);
  writeFileAtomic(mesh, bytes);
  return scene;
}

}  // namespace cpvs::server
