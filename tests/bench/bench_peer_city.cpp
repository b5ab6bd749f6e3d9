// The public peer's own city (../shared/scenes/loinesg-city, its sun), baked by `cpvs bake`
// as a user runs it, receivers everywhere and on surfaces (PCF 9), at each resolution:
// wall seconds, stage times, DAG and file bytes, peak memory, and the ratios against the
// peer's figures. The peer (loinesg/voxelized-shadows-improved, GL on a CPU rasterizer) is
// not part of this project: its figures are the ones measured beside ours on a 2-core
// machine (docs/measured.md, "The peer's city against the peer") and are printed as such,
// never re-measured here. Then an edit: one building moved, re-baked through the tile
// cache the original bake filled, against a full bake of the edited city (the files must
// match); with --with-256k, the procedural city at 256K. A program that prints, not a
// test: nothing here fails.
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
#include "cpvs/base/file.h"
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
constexpr unsigned kPeerDepthSlices = 4096;
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

/// The city with one building and its roof moved by (3, 0, 2) metres: every vertex listed
/// under those objects shifted (the file's other lines as they are). False when the file
/// names neither.
bool writeMovedBuilding(const std::string& from, const std::string& to) {
  std::ifstream in(from);
  std::ofstream out(to);
  std::string line, object;
  bool moved = false;
  while (std::getline(in, line)) {
    if (line.rfind("o ", 0) == 0) object = line.substr(2);
    if ((object == "004_building_01" || object == "071_building_01_roof") && line.rfind("v ", 0) == 0) {
      std::istringstream v(line.substr(2));
      double x = 0, y = 0, z = 0;
      v >> x >> y >> z;
      char buf[128];
      std::snprintf(buf, sizeof buf, "v %.17g %.17g %.17g", x + 3, y, z + 2);
      line = buf;
      moved = true;
    }
    out << line << "\n";
  }
  return moved && bool(out);
}

std::string mb(double bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f MB", bytes / 1e6);
  return buf;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> resolutions{"4K", "16K", "64K"}, editResolutions{"16K", "64K"};
  std::string scene = cpvs::testing::sharedScenesDir() + "/loinesg-city/city.obj";
  bool with256k = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--resolutions" && i + 1 < argc) {
      resolutions.clear();
      std::stringstream list(argv[++i]);
      for (std::string r; std::getline(list, r, ',');) resolutions.push_back(r);
    } else if (a == "--edit-resolutions" && i + 1 < argc) {
      editResolutions.clear();
      std::stringstream list(argv[++i]);
      for (std::string r; std::getline(list, r, ',');) editResolutions.push_back(r);
    } else if (a == "--scene" && i + 1 < argc) {
      scene = argv[++i];
    } else if (a == "--with-256k") {
      with256k = true;
    } else {
      std::fprintf(stderr,
                   "usage: bench_peer_city [--resolutions 4K,16K,64K] [--edit-resolutions 16K,64K] [--with-256k]\n"
                   "                       [--scene city.obj]\n"
                   "Bakes the peer's city with `cpvs bake` (receivers everywhere and surfaces) and prints the table\n"
                   "against the peer's figures; then one building moved, re-baked through a tile cache against a\n"
                   "full bake; with --with-256k, the procedural city at 256K (minutes).\n");
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
  std::printf("| R | depth slices | receivers | wall s | stages (s) | DAG | file | peak RSS | vs the peer: speed | bytes |\n");
  std::printf("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
  // Cubic grids, then above 4K the peer's own grid: 4096 slices deep at every resolution.
  std::vector<std::pair<std::string, std::string>> grids;
  for (const std::string& R : resolutions) {
    grids.push_back({R, ""});
    if (R != "4K" && R != "4096" && R != "1K" && R != "2K") grids.push_back({R, std::to_string(kPeerDepthSlices)});
  }
  for (const auto& [R, depth] : grids)
    for (const char* receivers : {"everywhere", "surfaces"}) {
      const std::string out = (dir / ("city-" + R + "-" + receivers + ".cpvs")).string();
      std::vector<std::string> args{CPVS_CLI, "bake", scene, "--sun-dir", kPeerSun, "--resolution", R, "--json", "-o", out};
      if (std::string(receivers) == "surfaces") args.insert(args.end(), {"--receivers", "surfaces", "--receiver-pcf", "9"});
      if (!depth.empty()) args.insert(args.end(), {"--depth-slices", depth});
      const std::string depthText = depth.empty() ? R + " (cubic)" : depth;
      const Run r = bake(args, (dir / "out.json").string());
      if (r.status != 0 || r.out.is_discarded()) {
        std::printf("| %s | %s | %s | failed (exit %d) | | | | | | |\n", R.c_str(), depthText.c_str(), receivers, r.status);
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
      std::printf("| %s | %s | %s | %.2f | %s | %s | %s | %.2f GB | %s | %s |\n", R.c_str(), depthText.c_str(), receivers, r.wall,
                  stages.str().c_str(), mb(dagBytes).c_str(), mb(r.out["file_bytes"].get<double>()).c_str(),
                  double(r.maxRssKb) / 1e6, speed.c_str(), bytes.c_str());
      std::fflush(stdout);
      fs::remove(out);
    }
  // An edit: one building moved, baked through a tile cache the original filled, against a
  // full bake of the edited city; the files must be the same.
  const std::string moved = (dir / "city-moved.obj").string();
  if (!editResolutions.empty() && writeMovedBuilding(scene, moved)) {
    std::printf("\n## One building moved (004_building_01 and its roof, by 3, 0, 2), receivers everywhere\n\n");
    std::printf("| R | first bake, cache written s | the edit through the cache s | tiles taken | full bake of the edit s | "
                "edit / full | same file |\n| --- | --- | --- | --- | --- | --- | --- |\n");
    for (const std::string& R : editResolutions) {
      const std::string cache = (dir / ("tiles-" + R)).string();
      auto args = [&](const std::string& file, const std::string& out, bool cached) {
        std::vector<std::string> v{CPVS_CLI, "bake", file, "--sun-dir", kPeerSun, "--resolution", R, "--json", "-o", out};
        if (cached) v.insert(v.end(), {"--tile-cache", cache});
        return v;
      };
      const std::string a = (dir / "a.cpvs").string(), b = (dir / "b.cpvs").string(), c = (dir / "c.cpvs").string();
      const Run first = bake(args(scene, a, true), (dir / "out.json").string());
      const Run edit = bake(args(moved, b, true), (dir / "out.json").string());
      const Run full = bake(args(moved, c, false), (dir / "out.json").string());
      if (first.status || edit.status || full.status || edit.out.is_discarded()) {
        std::printf("| %s | failed | | | | | |\n", R.c_str());
        continue;
      }
      std::printf("| %s | %.2f | %.2f | %llu of %llu | %.2f | %.0f %% | %s |\n", R.c_str(), first.wall, edit.wall,
                  static_cast<unsigned long long>(edit.out["tiles_reused"].get<uint64_t>()),
                  static_cast<unsigned long long>(edit.out["tiles"].get<uint64_t>()), full.wall,
                  100 * edit.wall / full.wall, cpvs::readFile(b) == cpvs::readFile(c) ? "yes" : "NO");
      std::fflush(stdout);
      fs::remove_all(cache);
      for (const std::string& f : {a, b, c}) fs::remove(f);
    }
  }
  if (with256k) {
    const std::string out = (dir / "city-256k.cpvs").string();
    const Run r = bake({CPVS_CLI, "bake", "city", "--sun-elevation", "35", "--sun-azimuth", "30", "--resolution", "256K",
                        "--json", "-o", out},
                       (dir / "out.json").string());
    if (r.status == 0 && !r.out.is_discarded())
      std::printf("\nThe procedural city at 256K (sun elevation 35, azimuth 30): %.1f s (target 120 s), DAG %s, peak "
                  "RSS %.2f GB\n",
                  r.wall, mb(r.out["bytes"].get<double>()).c_str(), double(r.maxRssKb) / 1e6);
    fs::remove(out);
  }
  std::printf("\nThe peer's grid is %u slices deep at every resolution (tiles of 4096^3 side by side); `--depth-slices %u`\n"
              "bakes the same voxels over the scene, in a cubic DAG whose slices behind the scene repeat its last.\n",
              kPeerDepthSlices, kPeerDepthSlices);
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
