// Tiles' sub-DAGs kept in a folder under their keys (tile_key.h), so that the next bake
// of an edited scene takes every tile no edit reached from here instead of baking it. A
// file per tile (the sub-DAG file a worker sends, checked as the coordinator checks it);
// bounded in bytes, the least recently used going first; kept across runs. A file that
// does not read back is a miss, never an error: the tile is baked again.
#pragma once

#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/base/hash.h"
#include "cpvs/dag/dag.h"

namespace cpvs {

class TileCache {
 public:
  /// Creates `folder` if needed; InputError when it cannot. `maxBytes`: what the folder may
  /// hold (older tiles are removed past it).
  TileCache(std::string folder, uint64_t maxBytes);

  /// The sub-DAG stored under `key` for tile (tileX, tileY), canonical and hashed as
  /// `options` bake, or none.
  std::optional<Dag> find(const Hash128& key, uint64_t tileX, uint64_t tileY, const BakeOptions& options);
  /// The same as the sub-DAG file's bytes (encodeSubDag), checked as find checks them: what
  /// a worker sends without decoding it again.
  std::optional<std::vector<uint8_t>> findFile(const Hash128& key, uint64_t tileX, uint64_t tileY,
                                               const BakeOptions& options);
  /// Stores `dag` under `key` (uncompressed: a cache trades disk for time), then trims
  /// the folder to its bound.
  void store(const Hash128& key, const Dag& dag);
  /// Stores a sub-DAG file's bytes under `key` (written whole, then renamed), then trims
  /// the folder to its bound. A disk that refuses the write loses only the cache's copy.
  void storeFile(const Hash128& key, const std::vector<uint8_t>& bytes);

  uint64_t hits() const { return hits_; }
  uint64_t misses() const { return misses_; }

 private:
  /// Reads and checks the file of `key`: the Dag, or none (a miss, counted).
  std::optional<Dag> read(const Hash128& key, uint64_t tileX, uint64_t tileY, const BakeOptions& options,
                          std::vector<uint8_t>* bytes);
  /// Counts the folder's tiles and removes the least recently used past the bound.
  void trim();
  std::string folder_;
  uint64_t maxBytes_;
  std::mutex mutex_;  // tiles are found and stored from the bake's threads
  uint64_t hits_ = 0, misses_ = 0;
  uint64_t total_ = 0;  // bytes in the folder, as last counted plus what was stored since
};

}  // namespace cpvs
