// Benchmark of light along segments through the sun's grid (sun shafts): nanoseconds per
// segment against its length in voxels, on the CPU (one thread) and on a Vulkan device
// (GPU timestamps around the dispatch), with how many blocks the walk visits against the
// voxels a dense walk would; then a frame of fog (`cpvs render --fog`'s) on the CPU. Prints
// the CPU model and the device. A program that prints, not a test.
#include <tbb/global_control.h>
#include <tbb/info.h>

#include <chrono>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "bench_common.h"
#include "cpvs/base/error.h"
#include "cpvs/base/progress.h"
#include "cpvs/eval/camera.h"
#include "cpvs/eval/render.h"
#include "cpvs/query/segment_walk.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/runtime/runtime.h"
#include "frame_timing.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

using namespace bench;

struct Args : CommonArgs {
  std::string device;
  int width = 1920, height = 1080;
  Medium medium{0.006, 0.001, 0.8};
};

void printUsage() {
  std::printf(
      "bench_shafts: light along segments through the sun's grid, and a frame of fog\n\n"
      "  --scenes LIST        city, bunny, teapots or paths (default city)\n"
      "  --resolutions LIST   default 4K,16K\n"
      "  --sun-dir X,Y,Z      the light direction\n"
      "  --frame WxH          the fog frame (default 1920x1080; 0x0: none)\n"
      "  --device TEXT        a Vulkan device whose name contains TEXT (else the best one)\n");
}

int run(int argc, char** argv) {
  Args a;
  a.scenes = {"city"};
  a.log2Resolutions = {12, 14};
  parseBenchArgs(argc, argv, a, [&](const std::string& option, const std::string& value) {
    if (option == "--device") a.device = value;
    else if (option == "--frame") {
      const size_t x = value.find('x');
      if (x == std::string::npos) throw InputError("--frame '" + value + "': expected WIDTHxHEIGHT");
      a.width = std::stoi(value.substr(0, x));
      a.height = std::stoi(value.substr(x + 1));
    } else return false;
    return true;
  });
  if (a.help) {
    printUsage();
    return 0;
  }
  std::unique_ptr<tbb::global_control> threads;
  if (a.threads > 0) threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, a.threads);
  std::printf("# Sun shafts: segments through the sun's grid\n\n%s, CPU: %s (%d threads for the frame)\n", now().c_str(),
              cpuModel().c_str(), a.threads > 0 ? a.threads : tbb::info::default_concurrency());
  runtime::DeviceOptions options;
  options.select = a.device;
  std::unique_ptr<runtime::GpuDevice> device = openTimingDevice(options);
  std::printf("Medium: scattering %g, absorption %g, g %g per world unit\n\n", a.medium.scattering, a.medium.absorption,
              a.medium.g);
  std::vector<std::string> notes;
  for (const std::string& spec : a.scenes) {
    std::optional<BenchScene> s = openBenchScene(spec, "bench_shafts", notes);
    if (!s) continue;
    for (int log2R : a.log2Resolutions) {
      const OrthoGrid grid = makeGrid(s->scene, LightFrame::fromDirection(a.sunDir), log2R);
      auto artifact = std::make_shared<const runtime::ShadowArtifact>(
          ShadowQuery(grid, PackedDag(testing::bakeWith(s->scene, grid, BakeOptions{}))));
      const ShadowQuery& q = artifact->cpu();
      std::unique_ptr<runtime::GpuShadows> gpu;
      if (device) gpu = std::make_unique<runtime::GpuShadows>(*device, artifact);
      std::printf("## %s at %s\n\n", s->label.c_str(), resolutionLabel(log2R).c_str());
      std::printf("| length (voxels) | segments | blocks walked | voxels crossed | CPU ns / segment | %s ns / segment | GPU = CPU |\n",
                  device ? "device" : "(no device)");
      std::printf("|---:|---:|---:|---:|---:|---:|---|\n");
      const double R = double(grid.resolution());
      std::mt19937_64 rng{uint64_t(log2R)};
      std::uniform_real_distribution<double> unit(0, 1);
      std::normal_distribution<double> gauss;
      for (double len = 16; len <= R; len *= 4) {
        const int count = int(std::max(2000.0, 2e6 / len));
        std::vector<Vec3> from, to;
        double blocks = 0, voxels = 0;
        for (int i = 0; i < count; ++i) {
          const Vec3 dir = normalize(Vec3{gauss(rng), gauss(rng), gauss(rng)});
          const Vec3 o{unit(rng) * R, unit(rng) * R, unit(rng) * R};
          from.push_back(grid.worldFromVoxel(o));
          to.push_back(grid.worldFromVoxel(o + dir * len));
          walkSegment(q.dag(), o, o + dir * len, [&](const SegmentPiece&) { blocks += 1; });
          voxels += std::abs(dir.x * len) + std::abs(dir.y * len) + std::abs(dir.z * len);
        }
        const auto start = std::chrono::steady_clock::now();
        std::vector<double> cpu(from.size());
        for (size_t i = 0; i < from.size(); ++i) cpu[i] = q.litFraction(from[i], to[i]);
        const double cpuNs = secondsSince(start) * 1e9 / double(count);
        std::string deviceNs = "n/a", same = "n/a";
        if (gpu) {
          std::vector<double> lit;
          std::vector<float> scattered;
          gpu->segments(from, to, a.medium, lit, scattered);  // warm
          gpu->segments(from, to, a.medium, lit, scattered);
          deviceNs = format("%.0f", gpu->lastSegmentNanoseconds() / double(count));
          same = lit == cpu ? "identical" : "DIFFERENT";
        }
        std::printf("| %.0f | %d | %.1f | %.1f | %.0f | %s | %s |\n", len, count, blocks / count, voxels / count, cpuNs,
                    deviceNs.c_str(), same.c_str());
      }
      if (a.width > 0 && a.height > 0) {
        const RayScene rays(s->scene, grid.origin);
        const Camera cam = defaultCamera(s->scene, grid.frame.dir, double(a.width) / a.height);
        const CameraHits hits = traceCamera(s->scene, rays, cam, a.width, a.height);
        const Image clear = shadeHits(hits, cpvsVisibility(hits, q, 3), grid.frame.dir);
        Vec3 lo, hi;
        sceneBounds(s->scene, lo, hi);
        const auto start = std::chrono::steady_clock::now();
        const Image fog = foggedImage(clear, hits, cam, q, a.medium, lo, hi);
        std::printf("\nA %dx%d frame of fog (render --fog, the default camera): %.1f ms on the CPU", a.width, a.height,
                    secondsSince(start) * 1e3);
        if (gpu) {
          // The frame's segments through the grid on the device (the rest of the frame is
          // shading a GPU does alongside).
          std::vector<Vec3> from, to;
          fogSegments(hits, cam, lo, hi, from, to);
          std::vector<double> lit;
          std::vector<float> scattered;
          gpu->segments(from, to, a.medium, lit, scattered);  // warm
          gpu->segments(from, to, a.medium, lit, scattered);
          std::printf("; its %zu segments %.1f ms on %s", from.size(), gpu->lastSegmentNanoseconds() * 1e-6,
                      device->name().c_str());
        }
        std::printf("\n\n");
      }
    }
  }
  for (const std::string& n : notes) std::printf("\n%s\n", n.c_str());
  return 0;
}

}  // namespace
}  // namespace cpvs

int main(int argc, char** argv) { return cpvs::bench::benchMain("bench_shafts", cpvs::run, argc, argv); }
