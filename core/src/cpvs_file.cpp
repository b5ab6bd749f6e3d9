#include "cpvs/cpvs_file.h"

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

class Writer {
 public:
  std::vector<uint8_t> bytes;
  template <class T>
  void put(T v) {
    static_assert(std::is_trivially_copyable_v<T>);
    size_t at = bytes.size();
    bytes.resize(at + sizeof(T));
    std::memcpy(bytes.data() + at, &v, sizeof(T));
  }
  void putVec(const Vec3& v) {
    put(v.x);
    put(v.y);
    put(v.z);
  }
  void raw(const void* p, size_t n) {
    size_t at = bytes.size();
    bytes.resize(at + n);
    if (n) std::memcpy(bytes.data() + at, p, n);
  }
};

class Reader {
 public:
  Reader(const uint8_t* d, size_t n, const std::string& src) : data_(d), size_(n), source_(src) {}
  template <class T>
  T get(const char* what) {
    need(sizeof(T), what);
    T v;
    std::memcpy(&v, data_ + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  Vec3 getVec(const char* what) {
    Vec3 v;
    v.x = get<double>(what);
    v.y = get<double>(what);
    v.z = get<double>(what);
    return v;
  }
  const uint8_t* take(size_t n, const char* what) {
    need(n, what);
    const uint8_t* p = data_ + pos_;
    pos_ += n;
    return p;
  }
  size_t pos() const { return pos_; }
  size_t remaining() const { return size_ - pos_; }
  [[noreturn]] void fail(const std::string& msg) const { throw InputError(source_ + ": " + msg); }

 private:
  void need(size_t n, const char* what) const {
    if (n > size_ - pos_)
      fail(std::string("truncated: the file ends inside the ") + what + " (at byte " +
           std::to_string(pos_) + " of " + std::to_string(size_) + ")");
  }
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
  std::string source_;
};

size_t pad4(size_t n) { return (n + 3) & ~size_t(3); }

void encodePayload(const Dag& dag, Writer& w) {
  w.raw(dag.leaves.data(), dag.leaves.size() * 8);
  for (const auto& lv : dag.levels) {
    w.raw(lv.codes.data(), lv.codes.size() * 2);
    if (lv.codes.size() % 2) w.put<uint16_t>(0);
    w.raw(lv.children.data(), lv.children.size() * 4);
  }
}

}  // namespace

std::vector<uint8_t> encodeCpvs(const CpvsArtifact& a, bool zstd) {
  const Dag& dag = a.dag;
  if (dag.roots.size() != 1 || dag.log2RootSize != dag.log2Resolution)
    throw std::invalid_argument("encodeCpvs: the DAG is not complete");
  Writer payload;
  encodePayload(dag, payload);

  Writer w;
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
  w.put<uint32_t>(uint32_t(dag.levels.size()));
  w.put<uint64_t>(dag.leaves.size());
  for (const auto& lv : dag.levels) {
    w.put<uint64_t>(lv.size());
    w.put<uint64_t>(lv.children.size());
  }
  w.put<uint64_t>(payload.bytes.size());
  if (zstd) {
    std::vector<uint8_t> packed(ZSTD_compressBound(payload.bytes.size()));
    size_t n = ZSTD_compress(packed.data(), packed.size(), payload.bytes.data(), payload.bytes.size(), 9);
    if (ZSTD_isError(n)) throw std::runtime_error(std::string("zstd: ") + ZSTD_getErrorName(n));
    packed.resize(n);
    w.put<uint64_t>(packed.size());
    w.raw(packed.data(), packed.size());
  } else {
    w.put<uint64_t>(payload.bytes.size());
    w.raw(payload.bytes.data(), payload.bytes.size());
  }
  w.put<uint64_t>(XXH3_64bits(w.bytes.data(), w.bytes.size()));
  return std::move(w.bytes);
}

CpvsArtifact decodeCpvs(const uint8_t* data, size_t size, const std::string& source) {
  Reader r(data, size, source);
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
  Reader h(data, size - 8, source);
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
  uint32_t levels = h.get<uint32_t>("level table");
  if (int(levels) != Dag::internalLevels(g.log2Resolution))
    h.fail(std::to_string(levels) + " levels do not match resolution 2^" + std::to_string(g.log2Resolution));
  dag.reset(g.log2Resolution, g.log2Resolution);
  uint64_t leafCount = h.get<uint64_t>("level table");
  std::vector<uint64_t> nodeCounts(levels), childCounts(levels);
  uint64_t expected = 0;
  constexpr uint64_t kMaxCount = std::numeric_limits<uint32_t>::max();
  if (leafCount > kMaxCount) h.fail("leaf count is out of range");
  expected += leafCount * 8;
  for (uint32_t l = 0; l < levels; ++l) {
    nodeCounts[l] = h.get<uint64_t>("level table");
    childCounts[l] = h.get<uint64_t>("level table");
    if (nodeCounts[l] > kMaxCount || childCounts[l] > 8 * nodeCounts[l])
      h.fail("level " + std::to_string(l) + " sizes are out of range");
    expected += pad4(nodeCounts[l] * 2) + childCounts[l] * 4;
  }
  uint64_t payloadSize = h.get<uint64_t>("level table");
  uint64_t storedSize = h.get<uint64_t>("level table");
  if (payloadSize != expected)
    h.fail("payload size " + std::to_string(payloadSize) + " does not match the level table (" +
           std::to_string(expected) + ")");
  if (storedSize != h.remaining())
    h.fail("payload is " + std::to_string(h.remaining()) + " bytes, the header says " + std::to_string(storedSize));
  const uint8_t* stored_ = h.take(storedSize, "payload");

  std::vector<uint8_t> unpacked;
  const uint8_t* payload = stored_;
  if (flags & kFlagZstd) {
    unsigned long long content = ZSTD_getFrameContentSize(stored_, storedSize);
    if (content == ZSTD_CONTENTSIZE_ERROR || content == ZSTD_CONTENTSIZE_UNKNOWN || content != payloadSize)
      h.fail("compressed payload is damaged");
    unpacked.resize(payloadSize);
    size_t n = ZSTD_decompress(unpacked.data(), unpacked.size(), stored_, storedSize);
    if (ZSTD_isError(n) || n != payloadSize) h.fail("compressed payload is damaged");
    payload = unpacked.data();
  } else if (storedSize != payloadSize) {
    h.fail("payload size does not match");
  }

  Reader p(payload, payloadSize, source);
  dag.leaves.resize(leafCount);
  std::memcpy(dag.leaves.data(), p.take(leafCount * 8, "leaves"), leafCount * 8);
  for (uint32_t l = 0; l < levels; ++l) {
    InternalLevel& lv = dag.levels[l];
    lv.codes.resize(nodeCounts[l]);
    std::memcpy(lv.codes.data(), p.take(nodeCounts[l] * 2, "node codes"), nodeCounts[l] * 2);
    if (nodeCounts[l] % 2) p.take(2, "node codes");
    lv.children.resize(childCounts[l]);
    std::memcpy(lv.children.data(), p.take(childCounts[l] * 4, "child indices"), childCounts[l] * 4);
    // Validate codes and child indices against the level below.
    uint64_t below = l == 0 ? leafCount : nodeCounts[l - 1];
    lv.childBegin.resize(nodeCounts[l] + 1);
    uint64_t at = 0;
    for (uint64_t i = 0; i < nodeCounts[l]; ++i) {
      lv.childBegin[i] = uint32_t(at);
      uint16_t c = lv.codes[i];
      if ((c & (c >> 1) & 0x5555u) != 0)
        p.fail("level " + std::to_string(l) + " node " + std::to_string(i) + " has an invalid child code");
      at += std::popcount(unsigned((c >> 1) & ~c & 0x5555u));
      if (at > childCounts[l]) p.fail("level " + std::to_string(l) + " holds more references than indices");
    }
    if (at != childCounts[l]) p.fail("level " + std::to_string(l) + " reference count does not match");
    lv.childBegin[nodeCounts[l]] = uint32_t(at);
    for (uint64_t k = 0; k < childCounts[l]; ++k)
      if (lv.children[k] >= below)
        p.fail("level " + std::to_string(l) + " child index " + std::to_string(lv.children[k]) +
               " is out of range (" + std::to_string(below) + " nodes below)");
  }
  uint64_t top = levels == 0 ? leafCount : nodeCounts[levels - 1];
  if (root.code > kRef || (root.code == kRef && root.index >= top)) p.fail("root reference is invalid");
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
