// Benchmark of shadow lookups at a frame's worth of camera-visible points (1920x1080 by
// default, sampleCameraViews of the default camera): binary and 9x9 PCF lookups on a
// Vulkan device (time from GPU timestamps around the dispatches, and wall time with the
// transfers) and on the CPU (all cores) in the same run, after checking that both give
// the same answers. Prints the CPU model, the device, and a Markdown table per scene and
// resolution. A program that prints, not a test.
#include <tbb/global_control.h>
#include <tbb/info.h>

#include <algorithm>
#include <filesystem>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "bench_common.h"
#include "cpvs/bake/bake_dag_mh.h"
#include "cpvs/base/parse.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/io/dmh_file.h"
#include "frame_timing.h"
#include "cpvs/base/error.h"
#include "cpvs/eval/camera.h"
#include "cpvs/eval/surface_sampling.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/runtime/runtime.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

using namespace bench;

struct Args : CommonArgs {
  std::string device;  // a name substring: CPVS_DEVICE's job
  int width = 1920, height = 1080;
  bool validation = false;
  std::string save;  // also write each artifact and frame here (for gpu_frame_timing)
  std::vector<std::string> formats{"cpvs"};
};

void printUsage() {
  std::printf(
      "bench_gpu_query: shadow lookups per frame on a Vulkan device and on the CPU\n\n"
      "  --scenes LIST        city, bunny, teapots or paths (default city,bunny)\n"
      "  --resolutions LIST   default 4K,16K\n"
      "  --sun-dir X,Y,Z      the light direction\n"
      "  --frame WxH          points per frame, from the default camera (default 1920x1080)\n"
      "  --device TEXT        a Vulkan device whose name contains TEXT (else the best one)\n"
      "  --validation on      the Khronos validation layer (slower; for checks)\n"
      "  --repeat N           timed frames per lookup kind (median; default 5)\n"
      "  --threads N          CPU threads (default: all)\n"
      "  --save DIR           also write each artifact and frame to DIR, for gpu_frame_timing\n"
      "  --formats LIST       cpvs, dagmh or both (default cpvs): a DAG-MH is baked for the surfaces\n"
      "                       its frame's points lie on, lookups up to 9x9\n");
}

int run(int argc, char** argv) {
  Args a;
  a.scenes = {"city", "bunny"};
  a.log2Resolutions = {12, 14};
  a.repeat = 5;
  parseBenchArgs(argc, argv, a, [&](const std::string& option, const std::string& value) {
    if (option == "--device") a.device = value;
    else if (option == "--save") a.save = value;
    else if (option == "--formats") {
      a.formats = splitList(value);
      for (const std::string& f : a.formats)
        if (f != "cpvs" && f != "dagmh") throw InputError("--formats '" + value + "': cpvs, dagmh or both");
    }
    else if (option == "--validation") a.validation = value == "on";
    else if (option == "--frame") {
      const size_t x = value.find('x');
      if (x == std::string::npos) throw InputError("--frame '" + value + "': expected WIDTHxHEIGHT");
      a.width = parsePositive(value.substr(0, x), "--frame");
      a.height = parsePositive(value.substr(x + 1), "--frame");
    } else return false;
    return true;
  });
  if (a.help) {
    printUsage();
    return 0;
  }
  std::unique_ptr<tbb::global_control> threads;
  if (a.threads > 0) threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, a.threads);
  const int cpuThreads = a.threads > 0 ? a.threads : tbb::info::default_concurrency();

  std::printf("# Shadow lookups per frame\n\n%s, CPU: %s (%d threads)\n", now().c_str(), cpuModel().c_str(), cpuThreads);
  runtime::DeviceOptions options;
  options.select = a.device;
  options.validation = a.validation;
  std::unique_ptr<runtime::GpuDevice> device = openTimingDevice(options);
  std::printf("Frame: %dx%d points a camera sees (sampleCameraViews of the default camera); median of %d frames\n\n",
              a.width, a.height, a.repeat);
  printTimingHeader();
  std::vector<std::string> notes;
  for (const std::string& spec : a.scenes) {
    std::optional<BenchScene> s = openBenchScene(spec, "bench_gpu_query", notes);
    if (!s) continue;
    for (int log2R : a.log2Resolutions) {
      OrthoGrid grid = makeGrid(s->scene, LightFrame::fromDirection(a.sunDir), log2R);
      const RayScene rays(s->scene, grid.origin);
      const double aspect = double(a.width) / a.height;
      const std::vector<Camera> cameras{defaultCamera(s->scene, grid.frame.dir, aspect)};
      Frame frame;
      for (const SurfaceSample& p : sampleCameraViews(s->scene, rays, cameras, aspect, uint64_t(a.width) * a.height, 1)) {
        frame.points.push_back(p.point);
        frame.normals.push_back(p.normal);
      }
      const std::string base = a.save + "/" + s->label + "-" + resolutionLabel(log2R);
      if (!a.save.empty()) {
        // What gpu_frame_timing reads on a machine with a GPU: the artifacts and the frame.
        std::filesystem::create_directories(a.save);
        writeFrame(base + ".frame", frame);
        frame = readFrame(base + ".frame");  // time what the other machine will time
      }
      for (const std::string& format : a.formats) {
        std::shared_ptr<const runtime::ShadowArtifact> artifact;
        if (format == "cpvs") {
          CpvsArtifact art;
          art.grid = grid;
          art.dag = testing::bakeWith(s->scene, grid, art.options);
          art.sceneHash = sceneHash(s->scene);
          if (!a.save.empty()) writeCpvs(base + ".cpvs", art, true);
          artifact = std::make_shared<const runtime::ShadowArtifact>(ShadowQuery(grid, PackedDag(art.dag)));
        } else {
          DmhArtifact art;
          art.grid = grid;
          ReceiverDeclaration surfaces;
          surfaces.kind = art.options.receivers = ReceiverKind::Surfaces;
          art.sceneHash = sceneHash(s->scene);
          art.receiverHash = receiverHash(surfaces);
          art.dag = bakeDagMh(s->scene, grid, art.options, surfaces);
          if (!a.save.empty()) writeDmh(base + ".dmh", art, true);
          artifact = std::make_shared<const runtime::ShadowArtifact>(DagMhQuery(grid, std::move(art.dag)));
        }
        printTimingRows(s->label + (format == "dagmh" ? " DAG-MH" : ""), resolutionLabel(log2R), artifact->bytes(),
                        artifact, frame, device.get(), a.repeat);
      }
    }
  }
  if (device && a.validation) std::printf("\nValidation messages: %zu\n", device->validationMessages().size());
  for (const std::string& n : notes) std::printf("\n%s\n", n.c_str());
  printTimingFooter();
  return 0;
}

}  // namespace
}  // namespace cpvs

int main(int argc, char** argv) { return cpvs::bench::benchMain("bench_gpu_query", cpvs::run, argc, argv); }
