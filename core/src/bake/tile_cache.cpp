#include "cpvs/bake/tile_cache.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <vector>

#include "cpvs/base/error.h"
#include "cpvs/base/file.h"
#include "cpvs/bake/tile_plan.h"
#include "cpvs/io/sub_dag_file.h"

namespace cpvs {

namespace fs = std::filesystem;

TileCache::TileCache(std::string folder, uint64_t maxBytes) : folder_(std::move(folder)), maxBytes_(maxBytes) {
  std::error_code ec;
  fs::create_directories(folder_, ec);
  if (!fs::is_directory(folder_, ec)) throw InputError("tile cache " + folder_ + ": cannot make the folder");
  // What a write cut short by a crash left (this process is the folder's one writer).
  for (const fs::directory_entry& e : fs::directory_iterator(folder_, ec))
    if (e.path().extension() == ".part") fs::remove(e.path(), ec);
  trim();
}

std::optional<Dag> TileCache::find(const Hash128& key, uint64_t tileX, uint64_t tileY, const BakeOptions& options) {
  return read(key, tileX, tileY, options, nullptr);
}

std::optional<std::vector<uint8_t>> TileCache::findFile(const Hash128& key, uint64_t tileX, uint64_t tileY,
                                                        const BakeOptions& options) {
  std::vector<uint8_t> bytes;
  if (!read(key, tileX, tileY, options, &bytes)) return std::nullopt;
  return bytes;
}

std::optional<Dag> TileCache::read(const Hash128& key, uint64_t tileX, uint64_t tileY, const BakeOptions& options,
                                   std::vector<uint8_t>* bytesOut) {
  const std::string path = folder_ + "/" + key.hex() + ".cpvt";
  std::error_code ec;
  try {
    if (!fs::exists(path, ec)) throw InputError("absent");
    std::vector<uint8_t> bytes = readFile(path);
    Dag dag = decodeSubDag(bytes.data(), bytes.size(), path, options.compress != CompressMode::None, options.hash);
    // The tile size as baked: at most the grid (TilePlan clamps it).
    checkTileRoots(dag, tileX, tileY, TilePlan(dag.log2Resolution, options.log2TileSize).log2TileSize(), path);
    fs::last_write_time(path, fs::file_time_type::clock::now(), ec);  // recently used
    if (bytesOut) *bytesOut = std::move(bytes);
    std::lock_guard lock(mutex_);
    ++hits_;
    return dag;
  } catch (const InputError&) {  // absent, torn or not this tile's: baked again
    std::lock_guard lock(mutex_);
    ++misses_;
    return std::nullopt;
  }
}

void TileCache::store(const Hash128& key, const Dag& dag) { storeFile(key, encodeSubDag(dag, false)); }

void TileCache::storeFile(const Hash128& key, const std::vector<uint8_t>& bytes) {
  const std::string path = folder_ + "/" + key.hex() + ".cpvt";
  // Its own name per write: two bakes may store one key at once (two jobs' equal tiles).
  static std::atomic<uint64_t> writes{0};
  const std::string part = path + "." + std::to_string(::getpid()) + "-" + std::to_string(writes++) + ".part";
  {
    std::ofstream out(part, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    if (!out) {
      std::error_code ec;
      fs::remove(part, ec);
      return;
    }
  }
  std::error_code ec;
  fs::rename(part, path, ec);
  if (ec) fs::remove(part, ec);
  std::lock_guard lock(mutex_);
  total_ += bytes.size();
  if (total_ > maxBytes_) trim();
}

void TileCache::trim() {
  struct Entry {
    fs::file_time_type used;
    uint64_t bytes;
    fs::path path;
  };
  std::vector<Entry> entries;
  uint64_t total = 0;
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(folder_, ec)) {
    if (e.path().extension() != ".cpvt") continue;
    const uint64_t size = e.file_size(ec);
    if (ec) continue;
    entries.push_back({e.last_write_time(ec), size, e.path()});
    total += size;
  }
  std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) { return a.used < b.used; });
  // Down to 7/8 of the bound, so that a full folder is not counted again at every store.
  const uint64_t target = total > maxBytes_ ? maxBytes_ - maxBytes_ / 8 : maxBytes_;
  for (const Entry& e : entries) {
    if (total <= target) break;
    if (fs::remove(e.path, ec)) total -= e.bytes;
  }
  total_ = total;
}

}  // namespace cpvs
