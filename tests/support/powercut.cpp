#include "powercut.h"

#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

namespace cpvs::testing {

namespace fs = std::filesystem;

namespace {

struct Entry {
  size_t at = 0;        // the journal line that made the name
  unsigned long long inode = 0;
  bool folder = false;
};

bool trustedName(const fs::path& p, const std::vector<std::string>& trusted) {
  const std::string name = p.filename().string();
  for (const std::string& t : trusted)
    if (name.rfind(t, 0) == 0) return true;
  return false;
}

unsigned long long inodeOf(const fs::path& p) {
  struct stat st;
  return ::lstat(p.c_str(), &st) == 0 ? st.st_ino : 0;
}

}  // namespace

PowerCut dropUnsyncedWrites(const std::string& journal, const std::string& folder, const std::vector<std::string>& trusted) {
  std::map<std::string, Entry> names;               // path -> how it came to be, this run
  std::map<std::string, size_t> folderSynced;       // folder path -> last sync line
  std::map<unsigned long long, uint64_t> durable;   // inode -> bytes synced (created or truncated this run)
  std::ifstream in(journal);
  std::string line;
  for (size_t at = 1; std::getline(in, line); ++at) {
    std::istringstream f(line);
    char kind = 0;
    f >> kind;
    unsigned long long inode = 0;
    std::string a, b;
    if (kind == 'C') {
      f >> inode >> a;
      names[a] = {at, inode, false};
      durable[inode] = 0;
    } else if (kind == 'T') {
      f >> inode;
      durable[inode] = 0;
    } else if (kind == 'M') {
      f >> a;
      names[a] = {at, 0, true};
    } else if (kind == 'S') {
      uint64_t size = 0;
      f >> inode >> size;
      durable[inode] = size;
    } else if (kind == 'D') {
      f >> a;
      folderSynced[a] = at;
    } else if (kind == 'R') {
      f >> inode >> a >> b;
      names.erase(a);
      names[b] = {at, inode, false};
    }
  }
  PowerCut cut;
  // Names first, shallowest first (a folder that goes takes what it held along).
  for (const auto& [path, entry] : names) {
    const std::string parent = fs::path(path).parent_path().string();
    const auto synced = folderSynced.find(parent);
    if (synced != folderSynced.end() && synced->second > entry.at) continue;
    if (!fs::exists(fs::symlink_status(path))) continue;
    if (!entry.folder && inodeOf(path) != entry.inode) continue;  // another file has the name now
    std::error_code ec;
    fs::remove_all(path, ec);
    cut.removed.push_back(path);
  }
  // Then contents: what was written after the last sync is lost.
  std::error_code ec;
  for (const auto& e : fs::recursive_directory_iterator(folder, ec)) {
    if (!e.is_regular_file() || trustedName(e.path(), trusted)) continue;
    const auto known = durable.find(inodeOf(e.path()));
    if (known == durable.end() || e.file_size() <= known->second) continue;
    fs::resize_file(e.path(), known->second);
    cut.truncated.push_back(e.path().string());
  }
  return cut;
}

}  // namespace cpvs::testing
