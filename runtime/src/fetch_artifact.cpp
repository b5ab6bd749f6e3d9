// A farm job's artifact in a local cache keyed by its content hash.
#include <sys/stat.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>

#include "cpvs/base/error.h"
#include "cpvs/base/file.h"
#include "cpvs/base/hash.h"
#include "cpvs/client/farm_client.h"
#include "cpvs/io/dmh_file.h"
#include "cpvs/runtime/runtime.h"

namespace cpvs::runtime {

namespace {

void makeFolder(const std::string& path) {
  if (::mkdir(path.c_str(), 0755) != 0 && errno != EEXIST)
    throw RuntimeError(Status::FileError, "cannot create " + path + ": " + std::strerror(errno));
}

// Job ids come from the farm: named in hex so that no id can leave the cache folder.
std::string fileNameOf(const std::string& jobId) {
  static const char* digits = "0123456789abcdef";
  std::string out;
  for (unsigned char c : jobId) out += {digits[c >> 4], digits[c & 15]};
  return out;
}

// The cached file a job's reference names (HASH.cpvs or HASH.dmh; a bare HASH, as older
// caches wrote it, is a .cpvs), when it is there and still matches its hash.
std::string cachedPath(const std::string& cacheDir, const std::string& ref) {
  std::ifstream in(ref);
  std::string name;
  if (!(in >> name)) return {};
  if (name.find('.') == std::string::npos) name += ".cpvs";
  const std::string checksum = name.substr(0, name.find('.')), extension = name.substr(checksum.size());
  if (checksum.size() != 32 || checksum.find_first_not_of("0123456789abcdef") != std::string::npos ||
      (extension != ".cpvs" && extension != ".dmh"))
    return {};
  const std::string path = cacheDir + "/" + name;
  try {
    const std::vector<uint8_t> bytes = readFile(path);
    if (contentHash(bytes.data(), bytes.size()).hex() == checksum) return path;
  } catch (const InputError&) {
  }
  return {};
}

}  // namespace

std::string fetchArtifact(const FarmAddress& farm, const std::string& jobId, const std::string& cacheDir, bool* fromCache) {
  if (jobId.empty()) throw RuntimeError(Status::InvalidArgument, "no job id");
  if (cacheDir.empty()) throw RuntimeError(Status::InvalidArgument, "no cache folder");
  makeFolder(cacheDir);
  makeFolder(cacheDir + "/jobs");
  makeFolder(cacheDir + "/incoming");
  const std::string ref = cacheDir + "/jobs/" + fileNameOf(jobId);
  if (std::string path = cachedPath(cacheDir, ref); !path.empty()) {
    if (fromCache) *fromCache = true;
    return path;
  }
  if (fromCache) *fromCache = false;
  const std::string incoming = cacheDir + "/incoming/" + fileNameOf(jobId) + ".cpvs";
  client::FarmClient::DownloadResult got;
  try {
    client::FarmClient client(net::Connection{farm.address, farm.token, farm.caFile});
    got = client.download(jobId, incoming);  // resumes incoming.part; verifies the checksum
  } catch (const client::FarmCallError& e) {
    throw RuntimeError(Status::FarmError, std::string("downloading job ") + jobId + " from " + farm.address + ": " + e.what());
  } catch (const InputError& e) {
    throw RuntimeError(Status::CorruptArtifact, e.what());
  }
  // Named by its kind, as the farm names it: a DAG-MH's file is a .dmh.
  std::string name = got.checksum + ".cpvs";
  {
    uint8_t magic[4] = {};
    std::ifstream head(incoming, std::ios::binary);
    if (head.read(reinterpret_cast<char*>(magic), 4) && isDmh(magic, 4)) name = got.checksum + ".dmh";
  }
  const std::string path = cacheDir + "/" + name;
  if (std::rename(incoming.c_str(), path.c_str()) != 0)
    throw RuntimeError(Status::FileError, "cannot move " + incoming + " to " + path + ": " + std::strerror(errno));
  try {
    syncParentFolder(path);
    const std::string line = name + "\n";
    writeFileAtomic(ref, std::vector<uint8_t>(line.begin(), line.end()));
  } catch (const InputError& e) {
    throw RuntimeError(Status::FileError, e.what());
  }
  return path;
}

}  // namespace cpvs::runtime
