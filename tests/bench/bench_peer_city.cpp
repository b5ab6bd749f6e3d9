// The public peer's own city (../shared/scenes/loinesg-city, its sun), baked by `cpvs bake`
// as a user runs it, receivers everywhere and on surfaces (PCF 9), at each resolution:
// wall seconds, stage times, DAG and file bytes, peak memory, and the ratios against the
// peer's figures. The peer (loinesg/voxelized-shadows-improved, GL on a CPU rasterizer) is
// not part of this project: its figures are the ones measured beside ours on a 2-core
// machine (docs/measured.md, "The peer's city against the peer") and are printed as such,
// never re-measured here. A program that prints, not a test: nothing here fails.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <iomanip>
#include <thread>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "bench_common.h"
#include "scene_testing.h"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The peer's sun for its city, and its figures (seconds, bytes) from the runs beside ours.
constexpr const char* kPeerSun = "0.505259,-0.379456,0.775066";
struct PeerRun {
  const char* resolution;
  double secondsLow, secondsHigh;
  uint64_t bytes;
};
constexpr PeerRun kPeer[] = {{"16K", 3.98, 5.52, 4447204}, {"64K", 57.6, 57.6, 17141128}};

struct Run {
  json out;        // cpvs bake --json
  double wall = 0; // seconds
  long maxRssKb = 0;
  int status = -1;
};

/// Runs `cpvs bake` as a child (its own peak memory, not this program's) with stdout to a file.
Run bake(const std::vector<std::string>& args, const std::string& stdoutPath) {
  Run r;
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  std::fflush(stdout);  // the child must not write this program's buffered table again
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid == 0) {
    FILE* f = std::freopen(stdoutPath.c_str(), "w", stdout);
    (void)f;
    std::freopen("/dev/null", "w", stderr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  int status = 0;
  rusage usage{};
  wait4(pid, &status, 0, &usage);
  r.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.maxRssKb = usage.ru_maxrss;
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  if (r.status == 0) {
    std::ifstream in(stdoutPath);
    r.out = json::parse(in, nullptr, false);
  }
  return r;
}

std::string mb(double bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f MB", bytes / 1e6);
  return buf;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> resolutions{"4K", "16K", "64K"};
  std::string scene = cpvs::testing::sharedScenesDir() + "/loinesg-city/city.obj";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--resolutions" && i + 1 < argc) {
      resolutions.clear();
      std::stringstream list(argv[++i]);
      for (std::string r; std::getline(list, r, ',');) resolutions.push_back(r);
    } else if (a == "--scene" && i + 1 < argc) {
      scene = argv[++i];
    } else {
      std::fprintf(stderr,
                   "usage: bench_peer_city [--resolutions 4K,16K,64K] [--scene city.obj]\n"
                   "Bakes the peer's city with `cpvs bake` (receivers everywhere and surfaces) and prints the table\n"
                   "against the peer's figures.\n");
      return 2;
    }
  }
  if (!fs::exists(scene)) {
    std::fprintf(stderr, "bench_peer_city: %s is absent (the shared scenes beside the project)\n", scene.c_str());
    return 2;
  }
  const fs::path dir = fs::temp_directory_path() / ("bench_peer_city_" + std::to_string(getpid()));
  fs::create_directories(dir);
  std::printf("# The peer's city, `cpvs bake` against the peer\n\n");
  std::printf("CPU: %s, %u threads; %s; scene %s, sun %s\n\n", cpvs::bench::cpuModel().c_str(),
              std::thread::hardware_concurrency(), cpvs::bench::now().c_str(), scene.c_str(), kPeerSun);
  std::printf("| R | receivers | wall s | stages (s) | DAG | file | peak RSS | vs the peer: speed | bytes |\n");
  std::printf("| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
  for (const std::string& R : resolutions)
    for (const char* receivers : {"everywhere", "surfaces"}) {
      const std::string out = (dir / ("city-" + R + "-" + receivers + ".cpvs")).string();
      std::vector<std::string> args{CPVS_CLI, "bake", scene, "--sun-dir", kPeerSun, "--resolution", R, "--json", "-o", out};
      if (std::string(receivers) == "surfaces") args.insert(args.end(), {"--receivers", "surfaces", "--receiver-pcf", "9"});
      const Run r = bake(args, (dir / "out.json").string());
      if (r.status != 0 || r.out.is_discarded()) {
        std::printf("| %s | %s | failed (exit %d) | | | | | | |\n", R.c_str(), receivers, r.status);
        continue;
      }
      std::ostringstream stages;
      for (const char* s : {"render", "receivers", "masks", "insert", "compress", "merge", "write"})
        if (r.out["stages"].contains(s) && r.out["stages"][s].get<double>() >= 0.05)
          stages << (stages.tellp() > 0 ? ", " : "") << s << " " << std::fixed << std::setprecision(1)
                 << r.out["stages"][s].get<double>();
      const double dagBytes = r.out["bytes"].get<double>();
      std::string speed = "-", bytes = "-";
      for (const PeerRun& p : kPeer)
        if (R == p.resolution) {
          char buf[64];
          std::snprintf(buf, sizeof buf, p.secondsLow == p.secondsHigh ? "%.2fx" : "%.2f-%.2fx", p.secondsLow / r.wall,
                        p.secondsHigh / r.wall);
          speed = buf;
          std::snprintf(buf, sizeof buf, "%.2fx", dagBytes / double(p.bytes));
          bytes = buf;
        }
      std::printf("| %s | %s | %.2f | %s | %s | %s | %.2f GB | %s | %s |\n", R.c_str(), receivers, r.wall,
                  stages.str().c_str(), mb(dagBytes).c_str(), mb(r.out["file_bytes"].get<double>()).c_str(),
                  double(r.maxRssKb) / 1e6, speed.c_str(), bytes.c_str());
      std::fflush(stdout);
      fs::remove(out);
    }
  std::printf("\nThe peer's figures (measured beside ours on a 2-core machine, docs/measured.md): ");
  for (const PeerRun& p : kPeer)
    std::printf("%s %.2f%s s, %llu B; ", p.resolution, p.secondsLow,
                p.secondsLow == p.secondsHigh ? "" : ("-" + std::to_string(p.secondsHigh).substr(0, 4)).c_str(),
                static_cast<unsigned long long>(p.bytes));
  std::printf("\nspeed: the peer's seconds over ours (> 1: faster); bytes: our DAG over the peer's (< 1: smaller).\n"
              "Stage times are summed over tiles; the bake overlaps two tiles, so they add up to more than the wall.\n");
  fs::remove_all(dir);
  return 0;
}
