// Benchmark of the light's depth maps, every renderer on the same texels in one run:
// bare Embree loops (closest hit on a fast and on a robust scene, all hits), the renderer
// as it was before the rasterizer (kept here, verbatim, as the baseline), the Embree
// renderer as it is, the rasterizer, the rasterizer with fused masks, and the bandwidth
// floor of writing 8 bytes per texel. Prints Markdown tables with ns per texel and the
// ratios between them, the CPU model and the SIMD target chosen, and checks in the same
// run that every texel where the rasterizer and Embree differ is ambiguous to the brute
// force. A program that prints, not a test.
#include <embree3/rtcore.h>
#include <emmintrin.h>
#include <sys/resource.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "bench_common.h"
#include "cpvs/bake/column_masks.h"
#include "cpvs/bake/raster_scene.h"
#include "cpvs/bake/raster_slices.h"
#include "cpvs/bake/texel_slices.h"
#include "cpvs/base/error.h"
#include "cpvs/base/parse.h"
#include "cpvs/base/progress.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/raytrace/ray_scene.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

using namespace bench;

// ---------------------------------------------------------------------------------------
// The renderer before the rasterizer (commit d602de4), the baseline "today's renderer":
// std::sort and std::stable_partition per texel, the approximate exit in two traversals,
// fresh buffers per call.

constexpr int kPacketW = 4, kPacketH = 2;

int legacyOrderCrossings(RayHit* hits, int count, double tieDistance) {
  std::sort(hits, hits + count, [](const RayHit& a, const RayHit& b) {
    if (a.t != b.t) return a.t < b.t;
    if (a.front != b.front) return a.front;
    return a.triangle < b.triangle;
  });
  // Surfaces that coincide (a box standing on another) are computed from different
  // triangles and land a few ulps apart in either order; within a run of crossings closer
  // than tieDistance, enters go first so that the count never touches zero between them.
  for (int i = 0; i < count;) {
    int j = i + 1;
    while (j < count && hits[j].t - hits[j - 1].t <= tieDistance) ++j;
    std::stable_partition(hits + i, hits + j, [](const RayHit& h) { return h.front; });
    i = j;
  }
  // A ray through a shared edge or vertex reports each triangle around it: crossings of
  // the same kind within tieDistance are one crossing.
  int n = 0;
  for (int i = 0; i < count; ++i) {
    bool dup = false;
    for (int j = n - 1; j >= 0 && std::abs(hits[i].t - hits[j].t) <= tieDistance; --j)
      if (hits[j].front == hits[i].front && hits[j].closed == hits[i].closed) {
        dup = true;
        break;
      }
    if (!dup) hits[n++] = hits[i];
  }
  return n;
}

void legacyClassifyTexel(const RayHit* hits, int count, bool exact, const TexelMapping& slices, uint32_t& lo, uint32_t& hi) {
  const uint32_t R = slices.side();
  if (count == 0) {
    lo = hi = R;
    return;
  }
  const RayHit& enter = hits[0];
  lo = hi = slices.slice(enter.t);
  // Only a closed surface entered from its front side opens an interior.
  if (!enter.closed || !enter.front) return;
  if (!exact) {
    for (int i = 1; i < count; ++i)
      if (hits[i].closed && !hits[i].front) {
        hi = std::max(lo, slices.slice(hits[i].t));
        return;
      }
    return;
  }
  int depth = 0;
  for (int i = 0; i < count; ++i) {
    if (!hits[i].closed) continue;
    depth += hits[i].front ? 1 : -1;
    if (depth < 0) return;  // inconsistent orientation: no interior is trusted
    if (depth == 0) {
      hi = std::max(lo, slices.slice(hits[i].t));
      return;
    }
  }
  // Never left the interior (open geometry forced closed): keep the column defined.
}

void legacyRenderTexelSlices(const RayScene& rays, const OrthoGrid& grid, ClosedMode closed, ExitMode exit,
                       uint64_t x0, uint64_t y0, uint32_t width, uint32_t height,
                       TexelSlices& out) {
  CPVS_CHECK(width % 8 == 0 && height % 8 == 0);
  const uint32_t R = static_cast<uint32_t>(grid.resolution());
  out.firstUndefined.assign(size_t(width) * height, R);
  out.firstShadowed.assign(size_t(width) * height, R);
  // Crossings closer than this are one crossing seen twice (Embree's robust mode reports
  // a ray through a shared edge on both triangles).
  const double dedupT = grid.sceneDepthExtent() * 1e-6;
  const bool exact = exit == ExitMode::Exact;
  const TexelMapping texels = grid.texelMapping(rays.origin());

  const uint32_t rowsOfPackets = height / kPacketH;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, rowsOfPackets, 4), [&](const auto& range) {
    std::array<RayCrossings, kPacketLanes> lanes;
    std::array<RayHit, kMaxHitsPerRay> sorted;
    std::array<RayHit, kPacketLanes> first, back;
    std::array<bool, kPacketLanes> found, foundBack;
    RayPacket packet;
    for (uint32_t pr = range.begin(); pr != range.end(); ++pr) {
      for (uint32_t px = 0; px < width; px += kPacketW) {
        for (int l = 0; l < kPacketLanes; ++l) {
          const uint64_t gx = x0 + px + (l % kPacketW), gy = y0 + uint64_t(pr) * kPacketH + (l / kPacketW);
          const TexelRay ray = texels.ray(gx, gy);
          packet.origin[size_t(l)] = ray.origin;
          packet.dir[size_t(l)] = ray.dir;
          packet.tNear[size_t(l)] = 0.0f;
          packet.tFar[size_t(l)] = float(ray.tMax);
          packet.active[size_t(l)] = true;
        }
        if (exact) {
          rays.allCrossings(packet, closed, lanes);
        } else {
          // Each lane's closest hit; lanes entering a closed front face get a second
          // pass for the first back face behind it.
          rays.firstHits(packet, closed, first, found);
          bool second = false;
          for (size_t l = 0; l < size_t(kPacketLanes); ++l) {
            lanes[l].count = found[l] ? 1 : 0;
            lanes[l].overflow = false;
            if (found[l]) lanes[l].hits[0] = first[l];
            packet.active[l] = found[l] && first[l].closed && first[l].front;
            packet.tNear[l] = found[l] ? float(first[l].t) : 0.0f;
            second = second || packet.active[l];
          }
          if (second) {
            rays.firstClosedBackFaces(packet, closed, back, foundBack);
            for (size_t l = 0; l < size_t(kPacketLanes); ++l)
              if (foundBack[l]) {
                lanes[l].hits[1] = back[l];
                lanes[l].count = 2;
              }
          }
        }

        for (int l = 0; l < kPacketLanes; ++l) {
          RayCrossings& lh = lanes[size_t(l)];
          int n = 0;
          if (!lh.overflow) {
            std::copy(lh.hits.begin(), lh.hits.begin() + lh.count, sorted.begin());
            n = legacyOrderCrossings(sorted.data(), lh.count, dedupT);
          } else {
            sorted[0] = lh.hits[0];  // too many crossings: keep the enter depth only
            for (int i = 1; i < lh.count; ++i)
              if (lh.hits[i].t < sorted[0].t) sorted[0] = lh.hits[i];
            sorted[0].closed = false;
            n = 1;
          }
          const uint32_t lx = px + (l % kPacketW), ly = pr * kPacketH + (l / kPacketW);
          const size_t at = size_t(ly) * width + lx;
          legacyClassifyTexel(sorted.data(), n, exact, texels, out.firstUndefined[at], out.firstShadowed[at]);
        }
      }
    }
  });
}

// ---------------------------------------------------------------------------------------
// Bare Embree loops: texel-centre rays in coherent packets of 8, nothing recorded but a
// checksum of the distances (closest hit) or the number of crossings (all hits).

struct BareScene {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  BareScene(const Scene& s, const Vec3& origin, bool robust) {
    device = rtcNewDevice(nullptr);
    scene = rtcNewScene(device);
    rtcSetSceneFlags(scene, robust ? RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION
                                   : RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), s.positions.size()));
    for (size_t i = 0; i < s.positions.size(); ++i) {
      const Vec3 p = s.positions[i] - origin;
      v[3 * i] = float(p.x), v[3 * i + 1] = float(p.y), v[3 * i + 2] = float(p.z);
    }
    auto* idx = static_cast<unsigned*>(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), s.triangleCount()));
    std::copy(s.indices.begin(), s.indices.end(), idx);
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(scene);
  }
  ~BareScene() {
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
  }
};

struct CountContext {
  RTCIntersectContext ctx;
  uint64_t* count;
};

void countFilter(const RTCFilterFunctionNArguments* args) {
  auto* c = reinterpret_cast<const CountContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i)
    if (args->valid[i] == -1) {
      ++*c->count;
      args->valid[i] = 0;
    }
}

double bareLoop(const BareScene& bare, const OrthoGrid& grid, uint64_t x0, uint64_t y0, uint32_t w, uint32_t h,
                bool allHits) {
  const TexelMapping texels = grid.texelMapping(grid.origin);
  std::atomic<uint64_t> total{0};
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, h / kPacketH, 4), [&](const auto& range) {
    double sum = 0;
    uint64_t count = 0;
    for (uint32_t pr = range.begin(); pr != range.end(); ++pr)
      for (uint32_t px = 0; px < w; px += kPacketW) {
        alignas(32) RTCRayHit8 rh;
        alignas(32) int valid[8];
        for (int l = 0; l < 8; ++l) {
          const TexelRay ray = texels.ray(x0 + px + uint64_t(l % kPacketW), y0 + uint64_t(pr) * kPacketH + uint64_t(l / kPacketW));
          rh.ray.org_x[l] = float(ray.origin.x), rh.ray.org_y[l] = float(ray.origin.y), rh.ray.org_z[l] = float(ray.origin.z);
          rh.ray.dir_x[l] = float(ray.dir.x), rh.ray.dir_y[l] = float(ray.dir.y), rh.ray.dir_z[l] = float(ray.dir.z);
          rh.ray.tnear[l] = 0, rh.ray.tfar[l] = float(ray.tMax), rh.ray.time[l] = 0, rh.ray.mask[l] = ~0u;
          rh.ray.id[l] = unsigned(l), rh.ray.flags[l] = 0, rh.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
          valid[l] = -1;
        }
        CountContext cc{{}, &count};
        rtcInitIntersectContext(&cc.ctx);
        cc.ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
        cc.ctx.filter = allHits ? countFilter : nullptr;
        rtcIntersect8(valid, bare.scene, &cc.ctx, &rh);
        for (int l = 0; l < 8; ++l)
          if (rh.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID) sum += rh.ray.tfar[l];
      }
    total += count + uint64_t(sum);
  });
  return double(total.load());
}

// ---------------------------------------------------------------------------------------
// The bandwidth floor: 8 bytes per texel (two 32-bit slices) written with streaming
// stores over the tile, in parallel.

void bandwidthFloor(std::vector<uint32_t>& a, std::vector<uint32_t>& b, size_t texels) {
  a.resize(texels + 4);
  b.resize(texels + 4);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, texels / 4096), [&](const auto& range) {
    const __m128i v = _mm_set1_epi32(int(range.begin()));
    for (size_t r = range.begin(); r != range.end(); ++r)
      for (size_t i = r * 4096; i < (r + 1) * 4096; i += 4) {
        _mm_stream_si128(reinterpret_cast<__m128i*>(a.data() + i), v);
        _mm_stream_si128(reinterpret_cast<__m128i*>(b.data() + i), v);
      }
  });
  _mm_sfence();
}

// ---------------------------------------------------------------------------------------
// Runs

enum Variant { kE0Fast, kE0Robust, kE1, kLegacy, kEmbree, kRaster, kMasks, kFused, kFloor, kVariants };
constexpr const char* kVariantNames[kVariants] = {"E0-fast", "E0-robust", "E1", "P", "P'", "Z", "M", "ZF", "B"};

struct Args : CommonArgs {
  Args() {
    log2Resolutions = {12, 14};
    repeat = 3;
  }
};

const char* kUsage =
    "usage: bench_depth [options]\n"
    "\n"
    "Renders the light's depth maps of each scene at each resolution with every renderer,\n"
    "on the same texels (all tiles of 4096^2), repetitions interleaved, and prints Markdown\n"
    "tables (stdout): ns per texel (minimum and median over the repetitions) and ratios.\n"
    "Variants: E0-fast / E0-robust (bare Embree closest hit, non-robust / robust scene),\n"
    "E1 (bare all hits), P (the renderer before the rasterizer), P' (the Embree renderer\n"
    "now), Z (the rasterizer), M (column masks from Z's slices), ZF (the rasterizer with\n"
    "fused masks), B (streaming 8 bytes per texel). Progress goes to stderr.\n"
    "\n"
    "options:\n"
    "  --resolutions LIST  comma-separated, e.g. 4K,16K (the default)\n"
    "  --scenes LIST       names or paths (default bunny,city,teapots)\n"
    "  --sun-dir X,Y,Z     light direction into the scene (default 0.35,-1,0.25)\n"
    "  --repeat N          repetitions of every variant, interleaved (default 3)\n"
    "  --threads N         worker threads (default: all cores)\n"
    "  --help              this text\n";

Args parseArgs(int argc, char** argv) {
  Args a;
  parseBenchArgs(argc, argv, a, [](const std::string&, const std::string&) { return false; });
  return a;
}

long minorFaults() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_minflt;
}

struct Timing {
  std::vector<double> seconds;
  long faults = 0;
  double min() const { return *std::min_element(seconds.begin(), seconds.end()); }
  double median() const {
    std::vector<double> s = seconds;
    std::sort(s.begin(), s.end());
    return s[s.size() / 2];
  }
};

struct Row {
  std::string scene;
  int log2R = 0;
  ExitMode exit = ExitMode::Exact;
  uint64_t texels = 0, tiles = 0;
  std::array<Timing, kVariants> t;
  uint64_t differ = 0, differAmbiguous = 0, rasterWrong = 0, embreeWrong = 0;
  bool checked = false;
  double ns(int v) const { return t[size_t(v)].seconds.empty() ? NAN : t[size_t(v)].min() * 1e9 / double(texels); }
};

// Every texel where the rasterizer and the Embree renderer differ, against the brute force.
void checkDifferences(const BenchScene& bs, const OrthoGrid& grid, ExitMode exit, uint64_t x0, uint64_t y0, uint32_t T,
                      const TexelSlices& raster, const TexelSlices& embree, Row& row) {
  row.checked = true;
  for (size_t i = 0; i < size_t(T) * T; ++i) {
    if (raster.firstUndefined[i] == embree.firstUndefined[i] && raster.firstShadowed[i] == embree.firstShadowed[i]) continue;
    ++row.differ;
    uint32_t lo = 0, hi = 0;
    bool ambiguous = false;
    testing::bruteForceTexel(bs.scene, grid, ClosedMode::Auto, exit, x0 + i % T, y0 + i / T, lo, hi, ambiguous);
    if (ambiguous) {
      ++row.differAmbiguous;
      continue;
    }
    row.rasterWrong += lo != raster.firstUndefined[i] || hi != raster.firstShadowed[i];
    row.embreeWrong += lo != embree.firstUndefined[i] || hi != embree.firstShadowed[i];
  }
}

int run(const Args& args) {
  std::unique_ptr<tbb::global_control> threadLimit;
  if (args.threads > 0)
    threadLimit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, args.threads);
  const LightFrame frame = LightFrame::fromDirection(args.sunDir);
  std::vector<std::string> notes;
  std::vector<BenchScene> scenes;
  for (const auto& spec : args.scenes)
    if (auto s = openBenchScene(spec, "bench_depth", notes)) scenes.push_back(std::move(*s));

  std::vector<Row> rows;
  std::vector<uint32_t> floorA, floorB;
  bandwidthFloor(floorA, floorB, size_t(4096) * 4096);  // its pages faulted in before any timing
  for (const BenchScene& bs : scenes) {
    for (int log2R : args.log2Resolutions) {
      const OrthoGrid grid = makeGrid(bs.scene, frame, log2R);
      const uint32_t T = uint32_t(std::min<uint64_t>(grid.resolution(), 4096));
      const uint64_t perSide = grid.resolution() / T;
      // Everything built before the clock starts: BVHs, the projection.
      RayScene rays(bs.scene, grid.origin);
      BareScene fast(bs.scene, grid.origin, false), robust(bs.scene, grid.origin, true);
      RasterScene raster(bs.scene, grid);
      for (ExitMode exit : {ExitMode::Exact, ExitMode::Approx}) {
        Row row;
        row.scene = bs.label;
        row.log2R = log2R;
        row.exit = exit;
        row.tiles = perSide * perSide;
        row.texels = grid.resolution() * grid.resolution();
        const bool bare = exit == ExitMode::Exact;  // the bare loops do not depend on the exit rule
        for (int rep = 0; rep < args.repeat; ++rep) {
          std::array<double, kVariants> seconds{};
          std::array<long, kVariants> faults{};
          for (uint64_t tile = 0; tile < row.tiles; ++tile) {
            const uint64_t x0 = (tile % perSide) * T, y0 = (tile / perSide) * T;
            auto timed = [&](int v, auto&& fn) {
              const long f0 = minorFaults();
              const auto start = std::chrono::steady_clock::now();
              fn();
              seconds[size_t(v)] += secondsSince(start);
              faults[size_t(v)] += minorFaults() - f0;
            };
            if (bare) {
              timed(kE0Fast, [&] { (void)bareLoop(fast, grid, x0, y0, T, T, false); });
              timed(kE0Robust, [&] { (void)bareLoop(robust, grid, x0, y0, T, T, false); });
              timed(kE1, [&] { (void)bareLoop(robust, grid, x0, y0, T, T, true); });
            }
            TexelSlices legacy, embree, rastered;
            timed(kLegacy, [&] { legacyRenderTexelSlices(rays, grid, ClosedMode::Auto, exit, x0, y0, T, T, legacy); });
            legacy = TexelSlices{};
            thread_local TexelSlices reused;  // the Embree renderer's buffers live across tiles, as in a bake
            timed(kEmbree, [&] { renderTexelSlices(rays, grid, ClosedMode::Auto, exit, x0, y0, T, T, reused); });
            timed(kRaster, [&] { rasterTexelSlices(raster, ClosedMode::Auto, exit, x0, y0, T, T, rastered); });
            ColumnMasks masks, fused;
            timed(kMasks, [&] { buildColumnMasks(rastered, T, T, uint32_t(grid.resolution()), UndefinedRule::New, masks); });
            timed(kFused, [&] {
              rasterColumnMasks(raster, ClosedMode::Auto, exit, UndefinedRule::New, x0, y0, T, T, fused);
            });
            timed(kFloor, [&] { bandwidthFloor(floorA, floorB, size_t(T) * T); });
            if (rep == 0 && log2R <= 12) checkDifferences(bs, grid, exit, x0, y0, T, rastered, reused, row);
            if (rep == 0 && (fused.slice != masks.slice || fused.mask != masks.mask))
              notes.push_back("WARNING: " + bs.label + " " + resolutionLabel(log2R) + ": fused masks differ from the unfused");
          }
          for (int v = 0; v < kVariants; ++v) {
            if (!bare && v <= kE1) continue;
            row.t[size_t(v)].seconds.push_back(seconds[size_t(v)]);
            row.t[size_t(v)].faults = faults[size_t(v)] / long(row.tiles);
          }
          std::fprintf(stderr, "bench_depth: %s %s %s repetition %d: P %.3f s, Z %.3f s, ZF %.3f s\n", bs.label.c_str(),
                       resolutionLabel(log2R).c_str(), optionName(exit), rep + 1, seconds[kLegacy], seconds[kRaster],
                       seconds[kFused]);
        }
        if (!bare) {  // the bare loops of the exact row serve both
          for (int v = kE0Fast; v <= kE1; ++v) row.t[size_t(v)] = rows.back().t[size_t(v)];
        }
        rows.push_back(std::move(row));
      }
    }
  }

  std::printf("Machine: %s, %u hardware threads, %d used; rasterizer SIMD target %s; %s\n", cpuModel().c_str(),
              std::thread::hardware_concurrency(),
              int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)), rasterInstructionSet(),
              now().c_str());
  std::printf("Sun direction %g,%g,%g; tiles of 4096^2; minimum of %d interleaved repetition%s.\n\n", args.sunDir.x,
              args.sunDir.y, args.sunDir.z, args.repeat, args.repeat == 1 ? "" : "s");
  std::printf("ns per texel (wall clock, all threads):\n\n| scene | R | exit |");
  for (const char* n : kVariantNames) std::printf(" %s |", n);
  std::printf("\n|---|---:|---|");
  for (int v = 0; v < kVariants; ++v) std::printf("---:|");
  std::printf("\n");
  for (const Row& r : rows) {
    std::printf("| %s | %s | %s |", r.scene.c_str(), resolutionLabel(r.log2R).c_str(), optionName(r.exit));
    for (int v = 0; v < kVariants; ++v) std::printf(" %s |", format("%.2f", r.ns(v)).c_str());
    std::printf("\n");
  }
  std::printf(
      "\nRatios: P / Z (today's renderer against the rasterizer, render alone), (P + M) / ZF (render and masks), "
      "P / P' (the Embree fixes), Z / E0-fast (below 1: faster than a bare closest-hit loop), E0-robust / E0-fast "
      "(the price of robust mode), E1 / E0-robust (the price of all hits), ZF / B (distance from the bandwidth "
      "floor); ZF Mtexel/s; page faults per tile of P, P' and ZF.\n\n");
  std::printf("| scene | R | exit | P / Z | (P + M) / ZF | P / P' | Z / E0-fast | E0-robust / E0-fast | E1 / E0-robust "
              "| ZF / B | ZF Mtexel/s | faults P / P' / ZF |\n|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const Row& r : rows)
    std::printf("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %ld / %ld / %ld |\n", r.scene.c_str(),
                resolutionLabel(r.log2R).c_str(), optionName(r.exit), times(ratio(r.ns(kLegacy), r.ns(kRaster))).c_str(),
                times(ratio(r.ns(kLegacy) + r.ns(kMasks), r.ns(kFused))).c_str(),
                times(ratio(r.ns(kLegacy), r.ns(kEmbree))).c_str(), format("%.3f", ratio(r.ns(kRaster), r.ns(kE0Fast))).c_str(),
                times(ratio(r.ns(kE0Robust), r.ns(kE0Fast))).c_str(), times(ratio(r.ns(kE1), r.ns(kE0Robust))).c_str(),
                times(ratio(r.ns(kFused), r.ns(kFloor))).c_str(), format("%.0f", 1e3 / r.ns(kFused)).c_str(),
                r.t[kLegacy].faults, r.t[kEmbree].faults, r.t[kFused].faults);
  std::printf("\nMedians (ns per texel) of P, P', Z, ZF: ");
  for (const Row& r : rows)
    std::printf("%s %s %s %.2f/%.2f/%.2f/%.2f; ", r.scene.c_str(), resolutionLabel(r.log2R).c_str(), optionName(r.exit),
                r.t[kLegacy].median() * 1e9 / double(r.texels), r.t[kEmbree].median() * 1e9 / double(r.texels),
                r.t[kRaster].median() * 1e9 / double(r.texels), r.t[kFused].median() * 1e9 / double(r.texels));
  std::printf("\n\nRasterizer against Embree, every texel where they differ checked by the brute force:\n\n");
  std::printf("| scene | R | exit | texels | differ | of them ambiguous | raster wrong | embree wrong |\n"
              "|---|---:|---|---:|---:|---:|---:|---:|\n");
  for (const Row& r : rows)
    if (r.checked)
      std::printf("| %s | %s | %s | %llu | %llu | %llu | %llu | %llu |\n", r.scene.c_str(), resolutionLabel(r.log2R).c_str(),
                  optionName(r.exit), (unsigned long long)r.texels, (unsigned long long)r.differ,
                  (unsigned long long)r.differAmbiguous, (unsigned long long)r.rasterWrong,
                  (unsigned long long)r.embreeWrong);
  if (!notes.empty()) std::printf("\n");
  for (const auto& n : notes) std::printf("%s\n", n.c_str());
  return 0;
}

}  // namespace
}  // namespace cpvs

int main(int argc, char** argv) {
  try {
    cpvs::Args args = cpvs::parseArgs(argc, argv);
    if (args.help) {
      std::fputs(cpvs::kUsage, stdout);
      return 0;
    }
    return cpvs::run(args);
  } catch (const cpvs::InputError& e) {
    std::fprintf(stderr, "bench_depth: error: %s\n", e.what());
    return 2;
  }
}
