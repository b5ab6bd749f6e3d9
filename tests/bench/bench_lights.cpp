// Benchmark of a light bundle's bake (seed 000 §5-6): the procedural city's street lamps,
// every grid at one resolution, baked in one process as `cpvs bake --scene-lights` does.
// Prints the machine, each grid's bytes and bake seconds (their distribution), the
// bundle's shared pool against the sum of separate DAGs and against 16-bit shadow maps of
// the same grids, and the whole bundle's wall time, with the targets beside them.
// Then one frame of many-light lookups (seed 000 §6.2): a camera's pixels, tiled light
// culling, and every (pixel, culled light) lookup with 9x9 PCF and binary, on the CPU and
// on a Vulkan device (lavapipe where no GPU is), their answers compared.
// A program that prints, not a test.
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "bench_common.h"
#include "frame_timing.h"
#include "cpvs/bake/bake_lights.h"
#include "cpvs/eval/camera.h"
#include "cpvs/query/light_tiles.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/runtime/runtime.h"
#include "cpvs/bake/raster_slices.h"
#include "cpvs/base/error.h"
#include "cpvs/base/parse.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/scene/source.h"

namespace cpvs {
namespace {

using namespace bench;

constexpr const char* kUsage =
    "bench_lights: bake the scene's own lights (the procedural city's street lamps) into one light bundle\n"
    "  --scene SPEC        scene with lights (default city: 12 blocks, 153 lamps)\n"
    "  --resolution R      every grid's resolution (default 8K, as seed 000's city)\n"
    "  --lights N          the first N lights only (default all)\n"
    "  --renderer raster|embree (default raster)\n"
    "  --receivers KIND    bake for these receivers (surfaces, surfaces-two-sided; PCF up to 9) and, in the same\n"
    "                      run, for receivers everywhere: bytes and seconds side by side (default everywhere only)\n"
    "  --threads N         worker threads (default all cores)\n"
    "  --width W, --height H  the many-light frame's size (default 1920 x 1080; --width 0: no frame)\n"
    "  --camera EX,EY,EZ,TX,TY,TZ[,FOV]  its camera (default: cpvs render's view of the scene)\n"
    "  --device NAME       a Vulkan device whose name holds NAME (default: the best; CPU figures only when none)\n"
    "  --save DIR          also write the bundle (DIR/lamps-R.lights) and the frame (.frame), for gpu_frame_timing\n";

struct Args {
  std::string scene = "city";
  int log2R = 13;
  size_t lights = 0;
  Renderer renderer = Renderer::Raster;
  int threads = 0;
  int width = 1920, height = 1080;
  std::string camera, device, save;
  ReceiverKind receivers = ReceiverKind::Everywhere;
  bool help = false;
};

Args parseArgs(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string o = argv[i];
    if (o == "--help" || o == "-h") {
      a.help = true;
      continue;
    }
    if (i + 1 >= argc) throw InputError(o + " needs a value (see --help)");
    const std::string v = argv[++i];
    if (o == "--scene") a.scene = v;
    else if (o == "--resolution") a.log2R = parseResolution(v);
    else if (o == "--lights") a.lights = size_t(parsePositive(v, o));
    else if (o == "--renderer") a.renderer = parseOption<Renderer>(v, o);
    else if (o == "--receivers") {
      a.receivers = parseOption<ReceiverKind>(v, o);
      if (a.receivers != ReceiverKind::Everywhere && a.receivers != ReceiverKind::Surfaces &&
          a.receivers != ReceiverKind::SurfacesTwoSided)
        throw InputError("--receivers: everywhere, surfaces or surfaces-two-sided (a volume or cameras need more flags)");
    }
    else if (o == "--threads") a.threads = parsePositive(v, o);
    else if (o == "--width") a.width = v == "0" ? 0 : parsePositive(v, o);
    else if (o == "--height") a.height = parsePositive(v, o);
    else if (o == "--camera") a.camera = v;
    else if (o == "--device") a.device = v;
    else if (o == "--save") a.save = v;
    else throw InputError("unknown option " + o + " (see --help)");
  }
  return a;
}

// The value at fraction q of sorted values.
double quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[std::min(v.size() - 1, size_t(q * double(v.size() - 1) + 0.5))];
}

// One frame's many-light lookups: the pixels a camera sees, the lights tiled culling
// leaves each 16 x 16 tile, and one lookup per (pixel, light of its tile), timed on the
// CPU and on a device with 9x9 PCF and binary.
void benchFrame(const Args& a, const Scene& scene, const LightBundle& bundle) {
  const auto artifact = std::make_shared<const runtime::LightArtifact>(bundle);
  const BundleQuery& query = artifact->cpu();
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  const RayScene rays(scene, (lo + hi) * 0.5);
  const Camera cam = a.camera.empty() ? defaultCamera(scene, Vec3{0.35, -1, 0.25}, double(a.width) / a.height)
                                      : Camera::parse(a.camera);
  const CameraHits hits = traceCamera(scene, rays, cam, a.width, a.height);
  // The pixels that see the scene; with --save, as gpu_frame_timing reads them back
  // (points and normals rounded as the file holds them), so both programs time the same.
  ManyLightFrame frame{a.width, a.height, {}, {}};
  for (size_t i = 0; i < hits.pixels.size(); ++i)
    if (hits.pixels[i].hit) {
      frame.pixels.push_back(uint32_t(i));
      frame.seen.points.push_back(hits.pixels[i].point);
      frame.seen.normals.push_back(hits.pixels[i].normal);
    }
  if (!a.save.empty()) {
    const std::string base = a.save + "/lamps-" + resolutionLabel(a.log2R);
    std::filesystem::create_directories(a.save);
    writeFileAtomic(base + ".lights", encodeBundle(bundle, true));
    writeManyLightFrame(base + ".frame", frame);
    frame = readManyLightFrame(base + ".frame");
    std::printf("\nsaved %s.lights and %s.frame (gpu_frame_timing)\n", base.c_str(), base.c_str());
  }
  auto t = std::chrono::steady_clock::now();
  const ManyLightQueries q = manyLightQueries(query, frame);
  const double cullSeconds = secondsSince(t);
  const std::vector<uint32_t>& lights = q.lights;
  const std::vector<Vec3>& points = q.frame.points;
  const std::vector<Vec3>& normals = q.frame.normals;
  const uint64_t pixels = frame.pixels.size();
  std::printf("\n## One frame of many-light lookups\n\n%d x %d, %llu pixels see the scene; culling over 16 x 16 tiles and "
              "listing the lookups: %.4f s on the CPU, %.2f lights per seen pixel, at most %u in a tile, %llu tiles over 64 "
              "(counted, never cut); %zu lookups a frame\n\n",
              a.width, a.height, (unsigned long long)pixels, cullSeconds, pixels ? double(points.size()) / double(pixels) : 0.0,
              q.tiles.longest, (unsigned long long)q.tiles.overflowing, points.size());
  std::unique_ptr<runtime::GpuDevice> device;
  std::unique_ptr<runtime::GpuLights> gpu;
  try {
    runtime::DeviceOptions options;
    options.select = a.device;
    device = runtime::GpuDevice::create(options);
    gpu = std::make_unique<runtime::GpuLights>(*device, artifact);
    std::printf("device: %s (%s), the pool in %d binding(s)\n\n", device->name().c_str(), device->type().c_str(),
                gpu->wordBindings());
  } catch (const runtime::RuntimeError& e) {
    std::printf("no device (%s): CPU figures only\n\n", e.what());
  }
  std::printf("| lookups | CPU wall (%d threads) | device time | device wall | CPU / device time | answers |\n"
              "|---|---:|---:|---:|---:|---|\n", int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)));
  for (int pcf : {9, 1}) {
    std::vector<uint32_t> onCpu, onGpu;
    runtime::cpuLightLitTexels(*artifact, lights, points, normals, pcf, onCpu);  // warm
    t = std::chrono::steady_clock::now();
    runtime::cpuLightLitTexels(*artifact, lights, points, normals, pcf, onCpu);
    const double cpu = secondsSince(t);
    std::string deviceTime = "-", deviceWall = "-", speedup = "-", same = "-";
    if (gpu) {
      gpu->litTexels(lights, points, normals, pcf, onGpu);  // warm
      t = std::chrono::steady_clock::now();
      gpu->litTexels(lights, points, normals, pcf, onGpu);
      const double wall = secondsSince(t), ns = gpu->lastDeviceNanoseconds();
      deviceTime = format("%.2f ms", ns / 1e6);
      deviceWall = format("%.1f ms", wall * 1e3);
      speedup = times(ratio(cpu * 1e9, ns));
      same = onGpu == onCpu ? "identical" : "DIFFER";
    }
    std::printf("| %s | %.1f ms | %s | %s | %s | %s |\n", pcf == 9 ? "9x9 PCF" : "binary", cpu * 1e3, deviceTime.c_str(),
                deviceWall.c_str(), speedup.c_str(), same.c_str());
  }
  // The pointer grid's depth (seed 000 §6.3): the same answers from a walk that starts
  // lower or at the root; what it costs in words and what it saves in time.
  std::printf("\n| pointer grid (levels) | pool words | 9x9 PCF CPU wall | device time | answers |\n|---|---:|---:|---:|---|\n");
  std::vector<uint32_t> reference;
  for (int levels : {5, 3, 0}) {
    const auto layout = std::make_shared<const runtime::LightArtifact>(withPointerGrids(bundle, levels));
    std::vector<uint32_t> onCpu, onGpu;
    runtime::cpuLightLitTexels(*layout, lights, points, normals, 9, onCpu);  // warm
    t = std::chrono::steady_clock::now();
    runtime::cpuLightLitTexels(*layout, lights, points, normals, 9, onCpu);
    const double cpu = secondsSince(t);
    if (reference.empty()) reference = onCpu;
    std::string deviceTime = "-";
    bool same = onCpu == reference;
    if (device) {
      runtime::GpuLights g(*device, layout);
      g.litTexels(lights, points, normals, 9, onGpu);  // warm
      g.litTexels(lights, points, normals, 9, onGpu);
      deviceTime = format("%.2f ms", g.lastDeviceNanoseconds() / 1e6);
      same = same && onGpu == reference;
    }
    std::printf("| %d | %zu | %.1f ms | %s | %s |\n", levels, layout->bundle().pool->size(), cpu * 1e3, deviceTime.c_str(),
                same ? "identical" : "DIFFER");
  }
  std::printf("\ntarget (issue): <= 2 ms a 1080p frame for all lights with 9x9 PCF on a data-center GPU; this device: %s\n",
              device ? device->name().c_str() : "none");
}

int run(const Args& a) {
  std::unique_ptr<tbb::global_control> limit;
  if (a.threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, a.threads);
  Scene scene = openScene(a.scene);
  std::vector<Light> lights = withSceneLights(scene, {}, a.scene);
  if (a.lights > 0 && a.lights < lights.size()) lights.resize(a.lights);
  for (Light& l : lights) l.log2Resolution = a.log2R;
  BakeOptions options;
  options.renderer = a.renderer;
  ReceiverDeclaration receivers;
  receivers.kind = a.receivers;
  options.receivers = a.receivers;

  std::printf("# bench_lights: %s, %s\n\nCPU: %s; rasterizer SIMD: %s; %s renderer; every grid %s^3\n\n", a.scene.c_str(),
              now().c_str(), cpuModel().c_str(), rasterInstructionSet(), optionName(a.renderer),
              resolutionLabel(a.log2R).c_str());
  std::vector<double> gridSeconds;  // each grid's wall seconds (grids bake side by side)
  const auto start = std::chrono::steady_clock::now();
  StageTimes stages;
  const LightBundle b =
      bakeLights(scene, lights, 1, options, sceneHash(scene), &stages, nullptr, &gridSeconds, receivers);
  const double wall = secondsSince(start);
  const std::vector<uint8_t> file = encodeBundle(b, true);
  std::printf("receivers: %s%s\n\n", optionName(a.receivers), a.receivers == ReceiverKind::Everywhere ? "" : ", PCF up to 9");

  std::vector<double> gridBytes;
  uint64_t separate = 0, maps = 0;
  for (const BundleGrid& g : b.grids) {
    gridBytes.push_back(double(g.bytes));
    separate += g.bytes;
    maps += 2 * g.grid.resolution() * g.grid.resolution();
  }
  std::printf("%zu lights, %zu grids\n\n", b.lights.size(), b.grids.size());
  std::printf("| per grid | min | median | 90th | max | total |\n|---|---:|---:|---:|---:|---:|\n");
  auto mb = [](double bytes) { return format("%.3f MB", bytes / 1e6); };
  std::printf("| bytes (its DAG alone) | %s | %s | %s | %s | %s |\n", mb(quantile(gridBytes, 0)).c_str(),
              mb(quantile(gridBytes, 0.5)).c_str(), mb(quantile(gridBytes, 0.9)).c_str(), mb(quantile(gridBytes, 1)).c_str(),
              mb(double(separate)).c_str());
  double bakeTotal = 0;
  for (double s : gridSeconds) bakeTotal += s;
  std::printf("| bake seconds | %s | %s | %s | %s | %s |\n\n", format("%.3f", quantile(gridSeconds, 0)).c_str(),
              format("%.3f", quantile(gridSeconds, 0.5)).c_str(), format("%.3f", quantile(gridSeconds, 0.9)).c_str(),
              format("%.3f", quantile(gridSeconds, 1)).c_str(), format("%.2f", bakeTotal).c_str());
  std::printf("| bundle | bytes | against the pool |\n|---|---:|---:|\n");
  std::printf("| shared node pool | %s | 1x |\n", mb(double(b.poolBytes)).c_str());
  std::printf("| separate DAGs (sum) | %s | %s |\n", mb(double(separate)).c_str(), times(ratio(double(separate), double(b.poolBytes))).c_str());
  std::printf("| 16-bit shadow maps of the same grids | %s | %s |\n", mb(double(maps)).c_str(),
              times(ratio(double(maps), double(b.poolBytes))).c_str());
  std::printf("| the file (zstd) | %s | %s |\n\n", mb(double(file.size())).c_str(),
              times(ratio(double(file.size()), double(b.poolBytes))).c_str());
  std::printf("| stage (summed over grids, which bake side by side) | seconds |\n|---|---:|\n");
  for (const char* name : kStageNames)
    if (auto it = stages.seconds.find(name); it != stages.seconds.end()) std::printf("| %s | %.2f |\n", name, it->second);
  std::printf("\ntiles not rendered (nothing there, or outside the cone): %llu\n\n", (unsigned long long)stages.tilesSkipped);
  std::printf("whole bundle: %.2f s wall (planning, %zu grid bakes, sharing, packing)\n", wall, b.grids.size());
  std::printf("targets (issue, the city's ~165 lamps at 8K, 2 cores): bundle <= 48 MB: %s (%s); whole bundle <= 120 s: %s (%.1f s)\n",
              b.poolBytes <= 48'000'000 ? "met" : "missed", mb(double(b.poolBytes)).c_str(), wall <= 120 ? "met" : "missed", wall);
  if (a.receivers != ReceiverKind::Everywhere) {
    // The baseline, in the same run: the same lights baked for receivers everywhere.
    BakeOptions everywhere = options;
    everywhere.receivers = ReceiverKind::Everywhere;
    const auto again = std::chrono::steady_clock::now();
    const LightBundle e = bakeLights(scene, lights, 1, everywhere, sceneHash(scene));
    const double eWall = secondsSince(again);
    const size_t eFile = encodeBundle(e, true).size();
    std::printf("\n| receivers | shared node pool | the file (zstd) | whole bundle wall |\n|---|---:|---:|---:|\n");
    std::printf("| everywhere | %s | %s | %.1f s |\n", mb(double(e.poolBytes)).c_str(), mb(double(eFile)).c_str(), eWall);
    std::printf("| %s (PCF up to 9) | %s (%s) | %s (%s) | %.1f s |\n", optionName(a.receivers), mb(double(b.poolBytes)).c_str(),
                times(ratio(double(b.poolBytes), double(e.poolBytes))).c_str(), mb(double(file.size())).c_str(),
                times(ratio(double(file.size()), double(eFile))).c_str(), wall);
  }
  if (a.width > 0) benchFrame(a, scene, b);
  return 0;
}

}  // namespace
}  // namespace cpvs

int main(int argc, char** argv) {
  try {
    const cpvs::Args args = cpvs::parseArgs(argc, argv);
    if (args.help) {
      std::fputs(cpvs::kUsage, stdout);
      return 0;
    }
    return cpvs::run(args);
  } catch (const cpvs::InputError& e) {
    std::fprintf(stderr, "bench_lights: error: %s\n", e.what());
    return 2;
  } catch (const cpvs::runtime::RuntimeError& e) {
    std::fprintf(stderr, "bench_lights: error: %s\n", e.what());
    return 1;
  }
}
