// The packed layout's bytes, measured per scene: one DAG as layout 1 holds it (a word per
// code and per reference), as layout 2 did (the 8^3 nodes in half-words), and as today's
// layout 3 (half-words throughout, 16-bit references where what they name fits), with
// the levels that need 32-bit references and the lookup nanoseconds of today's walk.
#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "bench_dags.h"
#include "cpvs/bake/raster_slices.h"
#include "cpvs/dag/packed_dag.h"
#include "cpvs/eval/surface_sampling.h"
#include "cpvs/query/shadow_query.h"
#include "cpvs/raytrace/ray_scene.h"

namespace {

using namespace cpvs;
using namespace cpvs::bench;

// The walk of layouts 1 and 2 as it was (PackedDag::block before layout 3), for the
// timing beside today's: the 8x8 mask of the leaf slice holding voxel (x, y, z).
uint64_t legacyMask(const uint32_t* w, const PackedHeader& h, uint64_t x, uint64_t y, uint64_t z) {
  uint32_t at = w[h.gridWord + gridCell(int(h.log2Resolution), int(h.gridLevels), x, y, z)];
  if (at >= kGridShadowed) return at == kGridShadowed ? ~uint64_t{0} : 0;
  for (int level = h.cellLevel(); level >= 0; --level) {
    const uint32_t codes = w[at];
    const int c = childOfVoxel(level, x, y, z);
    const uint32_t code = childCode(codes, c);
    if (code != kRef) return code == kShadowed ? ~uint64_t{0} : 0;
    const uint32_t rank = uint32_t(refRank(codes, c));
    if (level == 0 && h.wideRefs == 1) {  // layout 2: half-words at level 0
      const uint32_t half = 1 + rank;
      at = h.leafWord + 2 * ((w[at + half / 2] >> (16 * (half & 1))) & 0xFFFFu);
    } else {
      at = w[at + 1 + rank];
    }
  }
  return uint64_t(w[at]) | uint64_t(w[at + 1]) << 32;
}

// Nanoseconds per walk to the leaf slices of `voxels` on one core, for two walks timed
// in turn (seven rounds, the best of each: this machine's neighbours come and go); the
// two must answer alike.
template <class WalkA, class WalkB>
std::array<double, 2> walkNs(const std::vector<std::array<uint64_t, 3>>& voxels, const WalkA& a, const WalkB& b) {
  std::array<double, 2> best{1e30, 1e30};
  std::array<uint64_t, 2> sums{};
  auto time = [&](const auto& walk, int k) {
    uint64_t sum = 0;
    const auto start = std::chrono::steady_clock::now();
    for (const auto& v : voxels) sum += walk(v[0], v[1], v[2]);
    best[k] = std::min(best[k], std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    sums[k] = sum;
  };
  for (int r = 0; r < 7; ++r) {
    time(a, 0);
    time(b, 1);
  }
  if (sums[0] != sums[1]) throw std::runtime_error("the two walks answer differently");
  return {best[0] * 1e9 / double(voxels.size()), best[1] * 1e9 / double(voxels.size())};
}

// The levels whose references take two half-words, as "0-3" or "none".
std::string wideLevels(uint32_t mask) {
  std::string s;
  for (int l = 0; l < 32; ++l)
    if ((mask >> l) & 1) s += (s.empty() ? "" : ",") + std::to_string(l);
  return s.empty() ? "none" : s;
}

int run(int argc, char** argv) {
  CommonArgs args;
  args.scenes = {"peercity", "city", "shouse", "maisons", "bunny"};
  args.log2Resolutions = {12, 14};
  uint64_t lookups = 200000;
  parseBenchArgs(argc, argv, args, [&](const std::string& option, const std::string& value) {
    if (option != "--lookups") return false;
    lookups = uint64_t(parsePositive(value, option));
    return true;
  });
  if (args.help) {
    std::printf(
        "bench_layout [--scenes peercity,city,shouse,maisons,bunny] [--resolutions 4K,16K] [--sun-dir X,Y,Z] [--lookups N]\n"
        "  One DAG per scene, grid and receivers (everywhere; surfaces with PCF up to 9) in each packed layout:\n"
        "  bytes, the levels of 32-bit references, and ns per lookup (binary, 9x9) of today's walk at the\n"
        "  receivers' points. The peer's city takes its own sun, and above 4K also its grid of 4,096 slices.\n");
    return 0;
  }
  std::vector<std::string> notes;
  std::printf("CPU: %s, %s; %s\n\n", cpuModel().c_str(), rasterInstructionSet(), now().c_str());
  std::printf("| scene | R | depth slices | receivers | layout 1 | layout 2 | layout 3 | 3 / 2 | 3 / 1 | levels of 32-bit "
              "references | walk ns, layout 1 or 2 | walk ns, layout 3 | lookup ns 1 | lookup ns 9x9 |\n");
  std::printf("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
  forEachBenchDag(args, "bench_layout", notes, [&](const BenchDag& b) {
    const Dag& dag = b.dag;
    const RayScene rays(b.scene.scene, b.grid.origin);
    const uint64_t b1 = dag.bytes(1), b3 = dag.bytes();
    const bool fits2 = dag.leaves.size() <= kMaxNarrowRefTargets;  // layout 2 names leaves by 16 bits
    const uint64_t b2 = fits2 ? dag.bytes(2) : 0;
    const ShadowQuery query(b.grid, PackedDag(dag));
    const uint32_t wide = query.dag().header().wideRefs;
    std::vector<Vec3> points, normals;
    for (const SurfaceSample& p : sampleReceivers(b.scene.scene, rays, b.options.closed, b.grid.frame.dir, b.declaration, lookups, 1)) {
      points.push_back(p.point);
      normals.push_back(p.normal);
    }
    // The walks a 9x9 lookup makes: the leaf slices at the corners of the footprint
    // around each point's offset voxel, in the layout before (2 where it holds the
    // leaves, else 1) and today's.
    std::vector<std::array<uint64_t, 3>> voxels;
    const double last = double(b.grid.resolution() - 1);
    for (size_t i = 0; i < points.size(); ++i) {
      const Vec3 v = b.grid.offsetVoxel(points[i], normals[i], 5.5);
      const double z = std::clamp(std::floor(v.z), 0.0, last);
      for (const double dy : {-4.0, 4.0})
        for (const double dx : {-4.0, 4.0})
          voxels.push_back({uint64_t(std::clamp(std::floor(v.x + dx), 0.0, last)),
                            uint64_t(std::clamp(std::floor(v.y + dy), 0.0, last)), uint64_t(z)});
    }
    const std::vector<uint32_t> before = packPool(dag.leaves, dag.levels, {{dag.log2Resolution, dag.roots.front().ref}}, fits2 ? 2 : 1);
    PackedHeader hb;
    std::memcpy(&hb, before.data(), sizeof hb);
    const auto [nsBefore, nsToday] =
        walkNs(voxels, [&](uint64_t x, uint64_t y, uint64_t z) { return legacyMask(before.data(), hb, x, y, z); },
               [&](uint64_t x, uint64_t y, uint64_t z) { return query.dag().leafSliceMask(x, y, z); });
    std::printf("| %s | %s | %s | %s | %s | %s | %s | %.1f | %.1f | %.0f | %.0f |\n", benchDagCells(b).c_str(), humanBytes(b1).c_str(),
                fits2 ? humanBytes(b2).c_str() : "(> 65,536 leaves)", humanBytes(b3).c_str(),
                fits2 ? format("%.3f", ratio(double(b3), double(b2))).c_str() : "-",
                format("%.3f", ratio(double(b3), double(b1))).c_str(), wideLevels(wide).c_str(), nsBefore, nsToday,
                lookupNs(query, points, normals, 1), lookupNs(query, points, normals, 9));
  });
  for (const std::string& n : notes) std::printf("\nnote: %s", n.c_str());
  std::printf("\nBytes: the DAG's node data in each packed layout (the same nodes; 8 per leaf, 2 per half-word). Layout 2 "
              "named leaves by 16-bit index and holds at most 65,536. Walks: the leaf slices at the corners of the 9x9 footprints, one core, the best of seven rounds in turn; lookups: "
              "batched on all cores, best of three.\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return cpvs::bench::benchMain("bench_layout", run, argc, argv); }
