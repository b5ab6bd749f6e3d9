#include "coordinator/artifact_store.h"

#include <filesystem>

#include "cpvs/base/file.h"
#include "cpvs/io/dmh_file.h"

namespace cpvs::server {

namespace fs = std::filesystem;

ArtifactStore::ArtifactStore(const std::string& dataDir) : dataDir_(dataDir) {
  // Durable folders: a power cut must not take the folder of an acknowledged tile away.
  for (const char* sub : {"tiles", "artifacts"}) createFolderDurably((fs::path(dataDir_) / sub).string());
}

void ArtifactStore::createTileFolder(const std::string& jobId) const {
  createFolderDurably((fs::path(dataDir_) / "tiles" / jobId).string());
}

std::string ArtifactStore::tilePath(const std::string& jobId, uint64_t tile) const {
  return (fs::path(dataDir_) / "tiles" / jobId / (std::to_string(tile) + ".cpvt")).string();
}

void ArtifactStore::writeTile(const std::string& jobId, uint64_t tile, const std::vector<uint8_t>& bytes) const {
  writeFileAtomic(tilePath(jobId, tile), bytes);
}

std::vector<uint8_t> ArtifactStore::readTile(const std::string& jobId, uint64_t tile) const {
  return readFile(tilePath(jobId, tile));
}

void ArtifactStore::removeTiles(const std::string& jobId) const {
  std::error_code ec;
  fs::remove_all(fs::path(dataDir_) / "tiles" / jobId, ec);
}

std::vector<std::string> ArtifactStore::jobsWithTiles() const {
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(fs::path(dataDir_) / "tiles", ec))
    out.push_back(entry.path().filename().string());
  return out;
}

std::vector<std::string> ArtifactStore::jobsWithArtifacts() const {
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(fs::path(dataDir_) / "artifacts", ec))
    if (entry.path().extension() == ".cpvs" || entry.path().extension() == ".dmh")
      out.push_back(entry.path().stem().string());
  return out;
}

std::string ArtifactStore::artifactPath(const std::string& jobId, bool dagMh) const {
  return (fs::path(dataDir_) / "artifacts" / (jobId + (dagMh ? ".dmh" : ".cpvs"))).string();
}

void ArtifactStore::writeArtifact(const std::string& jobId, const std::vector<uint8_t>& bytes) const {
  writeFileAtomic(artifactPath(jobId, isDmh(bytes.data(), bytes.size())), bytes);
}

void ArtifactStore::removeArtifact(const std::string& jobId) const {
  std::error_code ec;
  for (const bool dagMh : {false, true}) fs::remove(artifactPath(jobId, dagMh), ec);
}

std::string ArtifactStore::withoutDataFolder(std::string text) const {
  for (const std::string& folder : {fs::absolute(dataDir_).lexically_normal().string(), dataDir_}) {
    if (folder.empty()) continue;
    for (size_t at = text.find(folder); at != std::string::npos; at = text.find(folder, at))
      text.replace(at, folder.size(), "the data folder");
  }
  return text;
}

}  // namespace cpvs::server
