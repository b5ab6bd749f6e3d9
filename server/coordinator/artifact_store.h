// Where the coordinator keeps bytes: tile results until their job's merge is done, and
// the finished artifacts. Paths only here; every write is atomic and durable.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cpvs::server {

class ArtifactStore {
 public:
  /// Creates tiles/ and artifacts/ under the data folder.
  explicit ArtifactStore(const std::string& dataDir);

  /// The folder for a new job's tile results, before any tile of it can be leased.
  void createTileFolder(const std::string& jobId) const;
  std::string tilePath(const std::string& jobId, uint64_t tile) const;
  /// Writes a tile result (InputError when the disk refuses).
  void writeTile(const std::string& jobId, uint64_t tile, const std::vector<uint8_t>& bytes) const;
  std::vector<uint8_t> readTile(const std::string& jobId, uint64_t tile) const;
  /// Removes the folder of a job's tile results (done, cancelled or failed jobs); best
  /// effort: a leftover folder costs disk, not correctness.
  void removeTiles(const std::string& jobId) const;
  /// The job ids that have a tile folder.
  std::vector<std::string> jobsWithTiles() const;

  /// A job's finished artifact: artifacts/<job>.cpvs, or <job>.dmh for a DAG-MH.
  std::string artifactPath(const std::string& jobId, bool dagMh = false) const;
  /// Writes it under the name its bytes' kind (their magic) gives.
  void writeArtifact(const std::string& jobId, const std::vector<uint8_t>& bytes) const;
  /// Removes an artifact, of either kind (of a job that ended otherwise while it was
  /// written, or pruned).
  void removeArtifact(const std::string& jobId) const;
  /// The job ids that have an artifact file.
  std::vector<std::string> jobsWithArtifacts() const;
  /// `text` with every mention of the data folder's path replaced by "the data folder":
  /// what a client is told names no path on the coordinator (R21).
  std::string withoutDataFolder(std::string text) const;

 private:
  std::string dataDir_;
};

}  // namespace cpvs::server
