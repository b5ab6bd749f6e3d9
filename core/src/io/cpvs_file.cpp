#include "cpvs/io/cpvs_file.h"

#include "cpvs/base/error.h"
#include "cpvs/base/limits.h"
#include "cpvs/base/text.h"
#include "cpvs/light/grid_spec.h"

#include "io/bake_fields.h"
#include "io/container.h"
#include "io/level_section.h"
#include "io/top_section.h"

#include <cmath>
#include <cstring>
#include <string>

namespace cpvs {
namespace {

/// Flag bit: a translucent casters' section follows the DAG.
constexpr uint32_t kCpvsTranslucent = 2;

}  // namespace

std::vector<uint8_t> encodeCpvs(const CpvsArtifact& a, bool zstd) {
  const Dag& dag = a.dag;
  CPVS_CHECK(dag.roots.size() == 1 && dag.log2RootSize == dag.log2Resolution);
  ByteWriter w;
  ContainerKind kind = kCpvsKind;
  kind.version = kCpvsFormatVersion;
  beginContainer(w, kind, (zstd ? kContainerZstd : 0) | (a.translucent ? kCpvsTranslucent : 0));
  putOrthoGrid(w, a.grid);
  putOptions(w, a.options, a.sceneHash);
  putReceiversAndPlan(w, a.options, a.receiverHash, a.plan);
  putWordSection(w, PackedDag(dag).words(), zstd);
  if (a.translucent) writeTopTree(*a.translucent, zstd, w);
  return sealContainer(std::move(w));
}

uint32_t cpvsFormatVersion(const uint8_t* data, size_t size, const std::string& source) {
  ByteReader r(data, size, source);
  if (std::memcmp(r.take(4, "magic number"), kCpvsKind.magic, 4) != 0) r.fail("not a .cpvs file (bad magic number)");
  return r.get<uint32_t>("header");
}

CpvsArtifact decodeCpvs(const uint8_t* data, size_t size, const std::string& source) {
  uint32_t flags = 0, version = 0;
  ByteReader h = openContainer(data, size, source, kCpvsKind, kContainerZstd | kCpvsTranslucent, flags, version);
  if (version == kBundleFormatVersion)
    h.fail("a light bundle (format " + std::to_string(version) + "), not a sun artifact: read it as a bundle");
  if ((flags & kCpvsTranslucent) && version < 3) h.fail("translucent casters in a format " + std::to_string(version) + " file");

  CpvsArtifact a;
  a.formatVersion = version;
  a.grid = getOrthoGrid(h);
  const OrthoGrid& g = a.grid;

  getOptions(h, a.options, a.sceneHash);
  if (version >= 3) getReceiversAndPlan(h, a.options, a.receiverHash, a.plan);

  const bool zstd = (flags & kContainerZstd) != 0;
  if (version >= 2) {
    std::vector<uint32_t> words = getWordSection(h, zstd, kPackedHeaderWords, "packed DAG");
    if (flags & kCpvsTranslucent) {
      TopTree tree = readTopTree(h, zstd);
      if (!tree.light().directional || length(tree.light().vector - g.frame.dir) > 1e-9)
        h.fail("its translucent casters' tree is for another light than its grid's sun");
      a.translucent = std::make_shared<const TopTree>(std::move(tree));
    }
    if (h.remaining() != 0) h.fail(std::to_string(h.remaining()) + " unexpected bytes after the payload");
    if (words[1] != uint32_t(g.log2Resolution))
      h.fail("the packed DAG is of resolution 2^" + std::to_string(words[1]) + ", the grid of 2^" + std::to_string(g.log2Resolution));
    try {
      a.packed = PackedDag::fromWords(std::move(words), a.dag);
    } catch (const InputError& e) {
      h.fail(e.what());
    }
    return a;
  }
  Dag& dag = a.dag;
  NodeRef root;
  root.code = h.get<uint32_t>("root");
  root.index = h.get<uint32_t>("root");
  const int levels = Dag::internalLevels(g.log2Resolution);
  dag.reset(g.log2Resolution, g.log2Resolution);
  readDagLevels(h, zstd, levels, dag);
  if (h.remaining() != 0) h.fail(std::to_string(h.remaining()) + " unexpected bytes after the payload");
  uint64_t top = levels == 0 ? dag.leaves.size() : dag.levels[levels - 1].size();
  if (root.code > kRef || (root.code == kRef && root.index >= top)) h.fail("root reference is invalid");
  dag.roots.push_back(Dag::Root{0, root});
  a.packed = PackedDag(dag);
  return a;
}

}  // namespace cpvs
