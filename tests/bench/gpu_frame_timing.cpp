// The lookups of bench_gpu_query from files, for a machine with a GPU and nothing else:
// every NAME.cpvs in DIR with its NAME.frame (bench_gpu_query --save DIR writes them),
// with dynamic casters NAME.casters where there are (bench_psv --save-casters), and every
// light bundle NAME.lights with its many-light NAME.frame (bench_lights --save DIR), timed
// on a Vulkan device and on the CPU. Links the runtime only (tests/gpu/device-check.sh
// carries it with its libraries).
//   gpu_frame_timing DIR [--device TEXT] [--repeat N]
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "frame_timing.h"

int main(int argc, char** argv) {
  using namespace cpvs;
  std::string dir, select;
  int repeat = 20;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--device" && i + 1 < argc) select = argv[++i];
    else if (arg == "--repeat" && i + 1 < argc) repeat = std::max(1, std::atoi(argv[++i]));
    else if (arg == "--help" || arg[0] == '-') {
      std::printf("usage: gpu_frame_timing DIR [--device TEXT] [--repeat N]\n");
      return arg == "--help" ? 0 : 2;
    } else dir = arg;
  }
  try {
    std::vector<std::filesystem::path> artifacts, bundles;
    for (const auto& e : std::filesystem::directory_iterator(dir)) {
      if (e.path().extension() == ".cpvs" || e.path().extension() == ".dmh") artifacts.push_back(e.path());
      if (e.path().extension() == ".lights") bundles.push_back(e.path());
    }
    std::sort(artifacts.begin(), artifacts.end());
    std::sort(bundles.begin(), bundles.end());
    if (artifacts.empty() && bundles.empty()) throw std::runtime_error("no .cpvs, .dmh or .lights files in " + dir);
    std::string model = "unknown";
    std::ifstream cpuinfo("/proc/cpuinfo");
    for (std::string line; std::getline(cpuinfo, line);)
      if (line.rfind("model name", 0) == 0) {
        model = line.substr(line.find(':') + 2);
        break;
      }
    std::printf("# Shadow lookups per frame\n\nCPU: %s\n", model.c_str());
    runtime::DeviceOptions options;
    options.select = select;
    std::unique_ptr<runtime::GpuDevice> device = bench::openTimingDevice(options);
    std::printf("Median of %d frames\n\n", repeat);
    if (!artifacts.empty()) bench::printTimingHeader();
    for (const auto& path : artifacts) {
      auto artifact = runtime::ShadowArtifact::open(path.string());
      std::filesystem::path framePath = path;
      framePath.replace_extension(".frame");
      const bench::Frame frame = bench::readFrame(framePath.string());
      const std::string stem = path.stem().string();
      const size_t dash = stem.rfind('-');
      bench::printTimingRows(stem.substr(0, dash) + (artifact->kind() == runtime::ArtifactKind::DagMh ? " DAG-MH" : ""),
                             stem.substr(dash + 1), artifact->bytes(), artifact, frame, device.get(), repeat);
    }
    if (!artifacts.empty()) bench::printTimingFooter();
    // Dynamic casters over an artifact's frame: NAME.casters beside NAME.cpvs and NAME.frame
    // (bench_psv --save-casters writes one).
    bool casterHeader = false;
    for (const auto& path : artifacts) {
      std::filesystem::path casters = path, framePath = path;
      casters.replace_extension(".casters");
      framePath.replace_extension(".frame");
      if (!std::filesystem::exists(casters)) continue;
      if (!casterHeader) {
        std::printf("\n## Dynamic casters per frame\n\n");
        bench::printCasterTimingHeader();
        casterHeader = true;
      }
      bench::printCasterTimingRows(path.stem().string(), runtime::ShadowArtifact::open(path.string()),
                                   bench::readCasters(casters.string()), bench::readFrame(framePath.string()),
                                   device.get(), repeat);
    }
    if (!bundles.empty()) {
      std::printf("\n## Many lights per frame\n\n");
      bench::printLightTimingHeader();
      for (const auto& path : bundles) {
        auto bundle = runtime::LightArtifact::open(path.string());
        std::filesystem::path framePath = path;
        framePath.replace_extension(".frame");
        const bench::ManyLightFrame frame = bench::readManyLightFrame(framePath.string());
        bench::printLightTimingRows(path.stem().string(), bundle, bench::manyLightQueries(bundle->cpu(), frame),
                                    device.get(), repeat);
      }
    }
    return device ? 0 : 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gpu_frame_timing: %s\n", e.what());
    return 2;
  }
}
