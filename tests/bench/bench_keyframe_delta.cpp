// How much consecutive sun keyframes share: for each scene and resolution, a keyframe at
// the base sun and one with the sun turned about the up axis by each step; the nodes of
// the second that the first already holds (nodes are content-addressed: the same 8x8
// mask, or the same codes over the same children), and what a delta of the rest would
// cost against the whole artifact, both zstd-compressed as artifacts are. The answer
// decides whether a subscriber is sent deltas or whole artifacts. A program that prints,
// not a test.
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <numbers>
#include <unordered_map>
#include <vector>

#include "bench_common.h"
#include "cpvs/base/error.h"
#include "cpvs/base/parse.h"
#include "cpvs/io/cpvs_file.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

using namespace bench;

// Content identities shared by every DAG interned into it: a leaf by its mask, a node by
// its codes and its children's identities.
class Interner {
 public:
  /// Identities of every leaf and every node of `dag`, per level (-1 first).
  std::vector<std::vector<uint64_t>> intern(const Dag& dag) {
    std::vector<std::vector<uint64_t>> ids(dag.levels.size() + 1);
    for (uint64_t leaf : dag.leaves) ids[0].push_back(idOf(leaves_, {leaf}));
    for (size_t l = 0; l < dag.levels.size(); ++l) {
      const InternalLevel& level = dag.levels[l];
      if (levels_.size() <= l) levels_.emplace_back();
      for (size_t i = 0; i < level.size(); ++i) {
        std::vector<uint64_t> key{level.codes[i]};
        for (uint32_t k = level.childBegin[i]; k < level.childBegin[i + 1]; ++k) key.push_back(ids[l][level.children[k]]);
        ids[l + 1].push_back(idOf(levels_[l], key));
      }
    }
    return ids;
  }

 private:
  struct KeyHash {
    size_t operator()(const std::vector<uint64_t>& v) const {
      uint64_t h = 1469598103934665603ull;
      for (uint64_t x : v) h = (h ^ x) * 1099511628211ull + (h >> 29);
      return size_t(h);
    }
  };
  using Table = std::unordered_map<std::vector<uint64_t>, uint64_t, KeyHash>;
  static uint64_t idOf(Table& t, std::vector<uint64_t> key) { return t.emplace(std::move(key), t.size()).first->second; }
  Table leaves_;
  std::vector<Table> levels_;
};

struct Sharing {
  uint64_t nodes = 0, sharedNodes = 0, bytes = 0, newBytes = 0, deltaZstd = 0;
};

// B's nodes that A holds (same level, same identity), and the zstd size of the others as
// they would be sent: leaves as 8 bytes, nodes as their code word and 4 bytes per child.
Sharing sharing(const Dag& a, const Dag& b, Interner& interner) {
  const auto idsA = interner.intern(a), idsB = interner.intern(b);
  Sharing s;
  std::vector<uint8_t> delta;
  auto append = [&](const void* p, size_t n) { delta.insert(delta.end(), (const uint8_t*)p, (const uint8_t*)p + n); };
  for (size_t l = 0; l < idsB.size(); ++l) {
    std::vector<uint64_t> held(idsA[l]);
    std::sort(held.begin(), held.end());
    for (size_t i = 0; i < idsB[l].size(); ++i) {
      const uint64_t bytes = l == 0 ? 8 : 4 + 4 * uint64_t(b.levels[l - 1].refCount(i));
      ++s.nodes;
      s.bytes += bytes;
      if (std::binary_search(held.begin(), held.end(), idsB[l][i])) {
        ++s.sharedNodes;
        continue;
      }
      s.newBytes += bytes;
      if (l == 0) {
        append(&b.leaves[i], 8);
      } else {
        const InternalLevel& level = b.levels[l - 1];
        const uint32_t codes = level.codes[i];
        append(&codes, 4);
        for (uint32_t k = level.childBegin[i]; k < level.childBegin[i + 1]; ++k) append(&level.children[k], 4);
      }
    }
  }
  std::vector<uint8_t> packed(ZSTD_compressBound(delta.size()));
  s.deltaZstd = ZSTD_compress(packed.data(), packed.size(), delta.data(), delta.size(), 9);
  return s;
}

Vec3 turnedAboutY(const Vec3& d, double degrees) {
  const double a = degrees * std::numbers::pi / 180, c = std::cos(a), s = std::sin(a);
  return {c * d.x + s * d.z, d.y, -s * d.x + c * d.z};
}

int run(int argc, char** argv) {
  CommonArgs a;
  a.scenes = {"city", "shouse"};
  a.log2Resolutions = {12, 14};
  std::vector<double> steps{0.25, 1, 5};
  parseBenchArgs(argc, argv, a, [&](const std::string& option, const std::string& value) {
    if (option != "--steps") return false;
    steps.clear();
    for (const std::string& part : splitList(value)) steps.push_back(parseDouble(part, "--steps"));
    return true;
  });
  if (a.help) {
    std::printf("bench_keyframe_delta: nodes shared by consecutive sun keyframes\n\n"
                "  --scenes LIST       default city,shouse\n  --resolutions LIST  default 4K,16K\n"
                "  --sun-dir X,Y,Z     the first keyframe's sun\n  --steps LIST        degrees about the up axis, default 0.25,1,5\n");
    return 0;
  }
  std::printf("# Nodes shared by consecutive keyframes\n\n%s, CPU: %s\n", now().c_str(), cpuModel().c_str());
  std::printf("Keyframe 2 = keyframe 1 with the sun turned about +Y by the step; shared = its nodes keyframe 1 holds.\n\n");
  std::printf("| scene | R | step | nodes | shared nodes | DAG bytes | bytes not held | artifact (zstd) | delta (zstd) | delta / artifact |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  std::vector<std::string> notes;
  for (const std::string& spec : a.scenes) {
    std::optional<BenchScene> s = openBenchScene(spec, "bench_keyframe_delta", notes);
    if (!s) continue;
    for (int log2R : a.log2Resolutions) {
      auto bake = [&](const Vec3& sun) {
        CpvsArtifact art;
        art.grid = makeGrid(s->scene, LightFrame::fromDirection(sun), log2R);
        art.dag = testing::bakeWith(s->scene, art.grid, art.options);
        art.sceneHash = sceneHash(s->scene);
        return art;
      };
      const CpvsArtifact first = bake(a.sunDir);
      for (double step : steps) {
        const CpvsArtifact second = bake(turnedAboutY(a.sunDir, step));
        Interner interner;
        const Sharing sh = sharing(first.dag, second.dag, interner);
        const uint64_t whole = encodeCpvs(second, true).size();
        std::printf("| %s | %s | %g° | %llu | %s | %s | %s | %s | %s | %s |\n", s->label.c_str(), resolutionLabel(log2R).c_str(),
                    step, static_cast<unsigned long long>(sh.nodes),
                    format("%.1f %%", 100.0 * double(sh.sharedNodes) / double(sh.nodes)).c_str(), humanBytes(sh.bytes).c_str(),
                    humanBytes(sh.newBytes).c_str(), humanBytes(whole).c_str(), humanBytes(sh.deltaZstd).c_str(),
                    format("%.2f", double(sh.deltaZstd) / double(whole)).c_str());
        std::fflush(stdout);
      }
    }
  }
  for (const std::string& n : notes) std::printf("\n%s\n", n.c_str());
  return 0;
}

}  // namespace
}  // namespace cpvs

int main(int argc, char** argv) { return cpvs::bench::benchMain("bench_keyframe_delta", cpvs::run, argc, argv); }
