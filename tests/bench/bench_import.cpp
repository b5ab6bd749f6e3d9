// What the import sandbox costs: each scene file imported in this process (assimp, no
// limits, the heap given back before each run as a program's one import finds it)
// against the way cpvs, cpvs-server and cpvs-worker import it (cpvs-import in a child process,
// limits, seccomp filter, the mesh sent back and checked). The minimum of --repeat runs
// each, alternated so that a slow moment hits both. Target: the isolation adds <= 10 %.
//
//   bench_import [--scenes city,house,FILE...] [--repeat N]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <thread>
#include <malloc.h>
#include <unistd.h>

#include "bench_common.h"
#include "cpvs/base/error.h"
#include "cpvs/base/progress.h"
#include "cpvs/scene/import.h"
#include "cpvs/scene/isolated_import.h"
#include "cpvs/scene/obj_writer.h"
#include "cpvs/scene/source.h"

namespace cpvs {
namespace {

namespace fs = std::filesystem;

/// A scene's file: the shared ones by name, a procedural city written as OBJ, or a path.
std::string sceneFile(const std::string& name, const fs::path& dir, std::vector<std::string>& notes) {
  const fs::path shared = fs::path(CPVS_SOURCE_DIR) / ".." / "shared" / "scenes";
  std::string path;
  if (name == "city") path = (shared / "loinesg-city/city.obj").string();
  else if (name == "house") path = (shared / "assimp-testmodels/AC14-FZK-Haus.ifc").string();
  else if (name == "town") path = (shared / "flightgear/zone_maisons.obj").string();
  else if (name.rfind("city:", 0) == 0) {
    path = (dir / (name.substr(5) + "-blocks.obj")).string();
    writeObj(path, openScene(name));
  } else {
    path = name;
  }
  if (!fs::exists(path)) {
    notes.push_back(name + ": " + path + " is absent, skipped");
    return {};
  }
  return path;
}

int run(int argc, char** argv) {
  bench::CommonArgs a;
  a.scenes = {"city", "house", "town", "city:12"};
  a.repeat = 15;
  bench::parseBenchArgs(argc, argv, a, [](const std::string&, const std::string&) { return false; });
  if (a.help) {
    std::printf("bench_import [--scenes city,house,town,city:BLOCKS,FILE...] [--repeat N]: in-process imports "
                "against cpvs-import's isolated ones\n");
    return 0;
  }
  const fs::path dir = fs::temp_directory_path() / ("cpvs_bench_import_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  ImportLimits limits;
  limits.helper = CPVS_IMPORT;
  limits.selfContained = false;  // as cpvs imports a local file
  std::printf("# The import sandbox's cost\n\n%s, CPU: %s, %u cores; the minimum of %d runs of each\n\n",
              bench::now().c_str(), bench::cpuModel().c_str(), std::thread::hardware_concurrency(), a.repeat);
  std::printf("| scene | file | triangles | in process, s | isolated (cpvs-import), s | overhead |\n");
  std::printf("|---|---:|---:|---:|---:|---:|\n");
  std::vector<std::string> notes;
  for (const std::string& name : a.scenes) {
    const std::string path = sceneFile(name, dir, notes);
    if (path.empty()) continue;
    double inProcess = 1e9, isolated = 1e9;
    SceneStats stats;
    for (int i = 0; i < a.repeat; ++i) {
      // The heap given back first, so that this import faults its pages in as a
      // program's one import does (a warm heap would flatter it by a third).
      malloc_trim(0);
      auto start = std::chrono::steady_clock::now();
      (void)loadScene(path, &stats, ImportOptions{false});
      inProcess = std::min(inProcess, secondsSince(start));
      start = std::chrono::steady_clock::now();
      (void)importIsolated(path, limits, nullptr, nullptr);
      isolated = std::min(isolated, secondsSince(start));
    }
    std::printf("| %s | %s | %llu | %.4f | %.4f | %+.1f %% |\n", name.c_str(),
                bench::humanBytes(fs::file_size(path)).c_str(), static_cast<unsigned long long>(stats.triangles),
                inProcess, isolated, 100 * (isolated / inProcess - 1));
    std::fflush(stdout);
  }
  for (const std::string& n : notes) std::printf("\n- %s", n.c_str());
  std::printf("\n");
  fs::remove_all(dir);
  return 0;
}

}  // namespace
}  // namespace cpvs

int main(int argc, char** argv) { return cpvs::bench::benchMain("bench_import", cpvs::run, argc, argv); }
