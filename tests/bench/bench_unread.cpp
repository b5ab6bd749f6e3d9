// What a fourth child code for blocks no receiver reads could save, per scene: the DAG
// baked as today, and the same DAG with every block that no lookup reads made lit (at
// every position it occupies, non-homogeneous or all shadowed, then shared again). A
// distinct code on those blocks merges nodes only where they agree on it, and lit merges
// with all of that and with the lit blocks beside them, so the second size bounds what
// such a code could reach. (It bounds no other choice of the free voxels' values.)
#include <algorithm>
#include <cstdio>
#include <random>
#include <string>
#include <unordered_map>
#include <vector>

#include "bench_dags.h"
#include "cpvs/bake/raster_slices.h"
#include "cpvs/bake/receivers.h"
#include "cpvs/base/error.h"

namespace {

using namespace cpvs;
using namespace cpvs::bench;

// Per 8x8-texel block of each level (level k: blocks of 8 << k texels), over its texels:
// the latest start and the earliest end of their free ranges (a block of slices inside
// both is read by no receiver anywhere in it), and whether any texel has a free range.
struct FreePyramid {
  struct Level {
    uint64_t width = 0;
    std::vector<uint32_t> latestStart, earliestEnd;
    std::vector<uint8_t> anyFree;
  };
  std::vector<Level> levels;

  FreePyramid(const TexelSlices& s, uint64_t R, size_t count) {
    levels.resize(count);
    Level& l0 = levels[0];
    l0.width = R / 8;
    l0.latestStart.assign(l0.width * l0.width, 0);
    l0.earliestEnd.assign(l0.width * l0.width, UINT32_MAX);
    l0.anyFree.assign(l0.width * l0.width, 0);
    for (uint64_t y = 0; y < R; ++y)
      for (uint64_t x = 0; x < R; ++x) {
        const size_t b = (y / 8) * l0.width + x / 8;
        const uint32_t lo = s.firstUndefined[y * R + x], hi = s.firstShadowed[y * R + x];
        l0.latestStart[b] = std::max(l0.latestStart[b], lo);
        l0.earliestEnd[b] = std::min(l0.earliestEnd[b], hi);
        l0.anyFree[b] |= uint8_t(hi > lo);
      }
    for (size_t k = 1; k < count; ++k) {
      const Level& below = levels[k - 1];
      Level& l = levels[k];
      l.width = std::max<uint64_t>(below.width / 2, 1);
      l.latestStart.assign(l.width * l.width, 0);
      l.earliestEnd.assign(l.width * l.width, UINT32_MAX);
      l.anyFree.assign(l.width * l.width, 0);
      for (uint64_t y = 0; y < below.width; ++y)
        for (uint64_t x = 0; x < below.width; ++x) {
          const size_t from = y * below.width + x, to = (y / 2) * l.width + x / 2;
          l.latestStart[to] = std::max(l.latestStart[to], below.latestStart[from]);
          l.earliestEnd[to] = std::min(l.earliestEnd[to], below.earliestEnd[from]);
          l.anyFree[to] |= below.anyFree[from];
        }
    }
  }
};

// The DAG rebuilt position by position with the unread blocks lit, equal nodes shared.
class UnreadLit {
 public:
  UnreadLit(const Dag& dag, const FreePyramid& free) : dag_(dag), free_(free) {
    out_.reset(dag.log2Resolution, dag.log2RootSize);
    copies_.resize(dag.levels.size());
    unique_.resize(dag.levels.size());
  }
  Dag run() {
    const int top = int(dag_.levels.size()) - 1;
    out_.roots.push_back({0, rewrite(top, dag_.roots.front().ref, 0, 0, 0)});
    return std::move(out_);
  }
  // The blocks nobody reads, met on the way (outermost only): non-homogeneous, all
  // shadowed (both made lit) and already lit.
  uint64_t unreadMixed = 0, unreadShadowed = 0, unreadLit = 0;

 private:
  void count(NodeRef ref) {
    (ref.code == kRef ? unreadMixed : ref.code == kShadowed ? unreadShadowed : unreadLit) += 1;
  }

  NodeRef rewrite(int level, NodeRef ref, uint64_t bx, uint64_t by, uint64_t bz) {
    const FreePyramid::Level& f = free_.levels[size_t(level)];
    const size_t at = by * f.width + bx;
    const uint64_t s = uint64_t(8) << level, z0 = bz * s, z1 = z0 + s;
    const bool unread = z0 >= f.latestStart[at] && z1 <= f.earliestEnd[at];
    if (unread) {
      count(ref);
      return {kLit, 0};
    }
    if (ref.code != kRef) return ref;
    if (!f.anyFree[at]) return {kRef, copy(level, ref.index)};  // every voxel read: as it is
    uint16_t codes = 0;
    uint32_t refs[kChildren];
    int n = 0;
    for (int c = 0; c < kChildren; ++c) {
      const NodeRef child = dag_.levels[size_t(level)].child(ref.index, c);
      NodeRef to = child;
      if (level == 0) {  // a depth slice of the 8x8 column
        const uint64_t z = z0 + uint64_t(c);
        const bool unread = z >= f.latestStart[at] && z + 1 <= f.earliestEnd[at];
        if (unread) {
          count(child);
          to = {kLit, 0};
        } else if (child.code == kRef) {
          to.index = leaf(dag_.leaves[child.index]);
        }
      } else {
        to = rewrite(level - 1, child, 2 * bx + (c & 1), 2 * by + (c >> 1 & 1), 2 * bz + (c >> 2 & 1));
      }
      codes |= uint16_t(to.code << (2 * c));
      if (to.code == kRef) refs[n++] = to.index;
    }
    if (codes == 0) return {kLit, 0};
    if (codes == 0x5555) return {kShadowed, 0};
    return {kRef, node(level, codes, refs, n)};
  }

  // Node `index` of `level` and everything under it, unchanged, shared as it goes.
  uint32_t copy(int level, uint32_t index) {
    const auto found = copies_[size_t(level)].find(index);
    if (found != copies_[size_t(level)].end()) return found->second;
    const InternalLevel& lv = dag_.levels[size_t(level)];
    uint32_t refs[kChildren];
    const uint32_t n = lv.refCount(index);
    for (uint32_t k = 0; k < n; ++k) {
      const uint32_t child = lv.children[lv.childBegin[index] + k];
      refs[k] = level == 0 ? leaf(dag_.leaves[child]) : copy(level - 1, child);
    }
    const uint32_t to = node(level, lv.codes[index], refs, int(n));
    copies_[size_t(level)].emplace(index, to);
    return to;
  }

  uint32_t leaf(uint64_t mask) {
    const auto [it, added] = leaves_.emplace(mask, uint32_t(out_.leaves.size()));
    if (added) out_.leaves.push_back(mask);
    return it->second;
  }

  uint32_t node(int level, uint16_t codes, const uint32_t* refs, int n) {
    std::string key(reinterpret_cast<const char*>(&codes), 2);
    key.append(reinterpret_cast<const char*>(refs), size_t(n) * 4);
    InternalLevel& lv = out_.levels[size_t(level)];
    const auto [it, added] = unique_[size_t(level)].emplace(std::move(key), uint32_t(lv.size()));
    if (added) lv.append(codes, refs);
    return it->second;
  }

  const Dag& dag_;
  const FreePyramid& free_;
  Dag out_;
  std::vector<std::unordered_map<uint32_t, uint32_t>> copies_;
  std::vector<std::unordered_map<std::string, uint32_t>> unique_;
  std::unordered_map<uint64_t, uint32_t> leaves_;
};

// Every sampled voxel that some receiver reads answers in both DAGs alike: the rewrite
// touched only what nobody reads. Returns the number that differ.
uint64_t readVoxelsThatDiffer(const Dag& a, const Dag& b, const TexelSlices& s, uint64_t R, uint64_t samples) {
  std::mt19937_64 rng(7);
  uint64_t differ = 0;
  for (uint64_t i = 0; i < samples; ++i) {
    const uint64_t x = rng() % R, y = rng() % R;
    const uint32_t lo = s.firstUndefined[y * R + x], hi = s.firstShadowed[y * R + x];
    uint64_t z = rng() % R;
    if (i % 2 == 0 && lo > 0) z = lo - 1 - rng() % std::min<uint64_t>(lo, 16);  // near the free range
    if (z >= lo && z < hi) continue;
    differ += dagVoxelShadowed(a, x, y, z) != dagVoxelShadowed(b, x, y, z);
  }
  return differ;
}

int run(int argc, char** argv) {
  CommonArgs args;
  args.scenes = {"peercity", "city", "shouse", "maisons", "bunny"};
  args.log2Resolutions = {12};
  parseBenchArgs(argc, argv, args, [](const std::string&, const std::string&) { return false; });
  if (args.help) {
    std::printf(
        "bench_unread [--scenes peercity,city,shouse,maisons,bunny] [--resolutions 4K] [--sun-dir X,Y,Z]\n"
        "  One DAG per scene and receivers (everywhere; surfaces with PCF up to 9), and the same DAG with every\n"
        "  block that no receiver's lookup reads made lit: the bound on what a distinct child code for unread blocks\n"
        "  could save. The peer's city takes its own sun, and above 4K also its grid of 4,096 slices. Holds the whole\n"
        "  grid's texels in memory (8 bytes each): 2 GiB at 16K.\n");
    return 0;
  }
  std::vector<std::string> notes;
  std::printf("CPU: %s; %s\n\n", cpuModel().c_str(), now().c_str());
  std::printf("| scene | R | depth slices | receivers | DAG | unread blocks lit | ratio | unread blocks: mixed | all shadowed | already lit | read voxels checked |\n");
  std::printf("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
  forEachBenchDag(args, "bench_unread", notes, [](const BenchDag& b) {
    const uint64_t R = b.grid.resolution();
    TexelSlices slices;
    rasterTexelSlices(b.prepared.raster(), b.options.closed, b.options.exit, 0, 0, uint32_t(R), uint32_t(R), slices);
    b.prepared.receivers().freeIntervals(0, 0, uint32_t(R), uint32_t(R), slices, false);
    const FreePyramid free(slices, R, b.dag.levels.size());
    UnreadLit rewrite(b.dag, free);
    const Dag lit = rewrite.run();
    const uint64_t samples = 1000000;
    const uint64_t differ = readVoxelsThatDiffer(b.dag, lit, slices, R, samples);
    if (differ) throw std::runtime_error(format("%.0f read voxels changed", double(differ)));
    std::printf("| %s | %s | %s | %.3f | %llu | %llu | %llu | %llu random, none differ |\n", benchDagCells(b).c_str(),
                humanBytes(b.dag.bytes()).c_str(), humanBytes(lit.bytes()).c_str(),
                ratio(double(lit.bytes()), double(b.dag.bytes())), static_cast<unsigned long long>(rewrite.unreadMixed),
                static_cast<unsigned long long>(rewrite.unreadShadowed), static_cast<unsigned long long>(rewrite.unreadLit),
                static_cast<unsigned long long>(samples));
  });
  for (const std::string& n : notes) std::printf("\nnote: %s", n.c_str());
  std::printf("\nDAG: today's bake, node data in today's packed layout. Unread blocks lit: the same DAG with every "
              "block (a node, or a leaf slice) whose voxels no receiver reads made lit, position by position, equal "
              "nodes shared again: the least a distinct child code on those blocks could keep. Unread blocks: the "
              "outermost ones met on the way, by what the bake had made of them. Read voxels: samples outside the free "
              "ranges (half of them just in front of one), compared in both DAGs.\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return cpvs::bench::benchMain("bench_unread", run, argc, argv); }
