#include "cpvs/cpvs_file.h"

#include "dag_payload.h"

#include <fcntl.h>
#include <unistd.h>
#include <xxhash.h>
#include <zstd.h>

#include <bit>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <limits>

namespace cpvs {

namespace {

constexpr char kMagic[4] = {'C', 'P', 'V', 'S'};
constexpr uint32_t kFlagZstd = 1;

}  // namespace

std::vector<uint8_t> encodeCpvs(const CpvsArtifact& a, bool zstd) {
  const Dag& dag = a.dag;
  if (dag.roots.size() != 1 || dag.log2RootSize != dag.log2Resolution)
    throw std::invalid_argument("encodeCpvs: the DAG is not complete");
  ByteWriter w;
  w.raw(kMagic, 4);
  w.put<uint32_t>(kCpvsFormatVersion);
  w.put<uint32_t>(zstd ? kFlagZstd : 0);
  const Grid& g = a.grid;
  w.putVec(g.frame.dir);
  w.putVec(g.frame.u);
  w.putVec(g.frame.v);
  w.putVec(g.origin);
  w.put(g.u0);
  w.put(g.v0);
  w.put(g.d0);
  w.put(g.extent);
  w.put(g.depthExtent);
  w.put<int32_t>(g.log2Resolution);
  const BakeOptions& o = a.options;
  w.put<uint8_t>(uint8_t(o.closed));
  w.put<uint8_t>(uint8_t(o.exit));
  w.put<uint8_t>(o.cull ? 1 : 0);
  w.put<uint8_t>(uint8_t(o.compress));
  w.put<uint8_t>(uint8_t(o.undefinedRule));
  w.put<uint8_t>(uint8_t(o.hash));
  w.put<uint16_t>(0);
  w.put<int32_t>(o.log2TileSize);
  w.put(a.sceneHash.lo);
  w.put(a.sceneHash.hi);
  w.put<uint32_t>(dag.roots[0].ref.code);
  w.put<uint32_t>(dag.roots[0].ref.index);
  writeDagLevels(dag, zstd, w);
  w.put<uint64_t>(XXH3_64bits(w.bytes.data(), w.bytes.size()));
  return std::move(w.bytes);
}

CpvsArtifact decodeCpvs(const uint8_t* data, size_t size, const std::string& source) {
  ByteReader r(data, size, source);
  const uint8_t* magic = r.take(4, "magic number");
  if (std::memcmp(magic, kMagic, 4) != 0) r.fail("not a .cpvs file (bad magic number)");
  uint32_t version = r.get<uint32_t>("header");
  if (version != kCpvsFormatVersion)
    r.fail("format version " + std::to_string(version) + " is not supported (this build reads version " +
           std::to_string(kCpvsFormatVersion) + ")");
  // Checksum first: every later check then reports real damage, not a random bit flip.
  if (size < 8 + r.pos()) r.fail("truncated: no room for the checksum");
  uint64_t stored;
  std::memcpy(&stored, data + size - 8, 8);
  if (XXH3_64bits(data, size - 8) != stored)
    r.fail("checksum mismatch: the file is corrupted or truncated");
  ByteReader h(data, size - 8, source);
  h.take(8, "header");
  uint32_t flags = h.get<uint32_t>("header");
  if (flags & ~kFlagZstd) h.fail("unknown flags " + std::to_string(flags));

  CpvsArtifact a;
  Grid& g = a.grid;
  g.frame.dir = h.getVec("header");
  g.frame.u = h.getVec("header");
  g.frame.v = h.getVec("header");
  g.origin = h.getVec("header");
  g.u0 = h.get<double>("header");
  g.v0 = h.get<double>("header");
  g.d0 = h.get<double>("header");
  g.extent = h.get<double>("header");
  g.depthExtent = h.get<double>("header");
  g.log2Resolution = h.get<int32_t>("header");
  if (g.log2Resolution < kMinLog2Resolution || g.log2Resolution > kMaxLog2Resolution)
    h.fail("resolution 2^" + std::to_string(g.log2Resolution) + " is out of range");
  for (double v : {g.u0, g.v0, g.d0, g.extent, g.depthExtent})
    if (!std::isfinite(v)) h.fail("grid holds a non-finite value");
  if (!(g.extent > 0) || !(g.depthExtent > 0)) h.fail("grid extent is not positive");
  for (const Vec3* v : {&g.frame.dir, &g.frame.u, &g.frame.v, &g.origin})
    if (!isFinite(*v)) h.fail("light frame holds a non-finite value");
  if (std::abs(length(g.frame.dir) - 1) > 1e-6) h.fail("light direction is not normalized");

  BakeOptions& o = a.options;
  uint8_t opt[6];
  for (auto& b : opt) b = h.get<uint8_t>("options");
  if (opt[0] > 2 || opt[1] > 1 || opt[2] > 1 || opt[3] > 2 || opt[4] > 1 || opt[5] > 1)
    h.fail("options hold an unknown value");
  o.closed = ClosedMode(opt[0]);
  o.exit = ExitMode(opt[1]);
  o.cull = opt[2] != 0;
  o.compress = CompressMode(opt[3]);
  o.undefinedRule = UndefinedRule(opt[4]);
  o.hash = HashKind(opt[5]);
  h.get<uint16_t>("options");
  o.log2TileSize = h.get<int32_t>("options");
  a.sceneHash.lo = h.get<uint64_t>("header");
  a.sceneHash.hi = h.get<uint64_t>("header");

  Dag& dag = a.dag;
  NodeRef root;
  root.code = h.get<uint32_t>("root");
  root.index = h.get<uint32_t>("root");
  const int levels = Dag::internalLevels(g.log2Resolution);
  dag.reset(g.log2Resolution, g.log2Resolution);
  readDagLevels(h, (flags & kFlagZstd) != 0, levels, dag);
  if (h.remaining() != 0) h.fail(std::to_string(h.remaining()) + " unexpected bytes after the payload");
  uint64_t top = levels == 0 ? dag.leaves.size() : dag.levels[levels - 1].size();
  if (root.code > kRef || (root.code == kRef && root.index >= top)) h.fail("root reference is invalid");
  dag.roots.push_back(Dag::Root{0, root});
  return a;
}

void writeFileAtomic(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::string tmp = path + ".tmp." + std::to_string(::getpid());
  int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd < 0) throw InputError("cannot write " + path + ": " + std::strerror(errno));
  size_t done = 0;
  while (done < bytes.size()) {
    ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      int e = errno;
      ::close(fd);
      ::unlink(tmp.c_str());
      throw InputError("cannot write " + path + ": " + std::strerror(e));
    }
    done += size_t(n);
  }
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    ::unlink(tmp.c_str());
    throw InputError("cannot write " + path + ": " + std::strerror(errno));
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    int e = errno;
    ::unlink(tmp.c_str());
    throw InputError("cannot write " + path + ": " + std::strerror(e));
  }
}

std::vector<uint8_t> readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError("cannot open " + path + ": " + std::strerror(errno));
  in.seekg(0, std::ios::end);
  std::streamoff n = in.tellg();
  if (n < 0) throw InputError("cannot read " + path);
  in.seekg(0);
  std::vector<uint8_t> bytes(static_cast<size_t>(n));
  if (n > 0 && !in.read(reinterpret_cast<char*>(bytes.data()), n)) throw InputError("cannot read " + path);
  return bytes;
}

}  // namespace cpvs
