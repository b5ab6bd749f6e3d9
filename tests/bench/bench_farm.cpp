// Farm benchmark: the same bake in one process (`cpvs bake`), on a farm with one worker
// and on a farm with two, all on this machine. Prints one table: wall times, speedup
// against the local bake, tiles per second, the coordinator's merge time as a share of
// the total, the merge's peak partial-DAG bytes and the coordinator's peak memory (RSS).
#include <nlohmann/json.hpp>
#include <sys/wait.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "cpvs/io/cpvs_file.h"
#include "cpvs/scene/source.h"
#include "process_testing.h"

namespace {

namespace fs = std::filesystem;
using cpvs::testing::ChildProcess;

struct Ran {
  int status = -1;
  std::string out;
  double seconds = 0;
};

Ran run(const std::string& cmd) {
  auto start = std::chrono::steady_clock::now();
  Ran r;
  FILE* p = popen((cmd + " 2>/dev/null").c_str(), "r");
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.out.append(buf.data(), n);
  int raw = pclose(p);
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

/// Peak resident memory of a live process in bytes (VmHWM).
uint64_t peakRss(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string key;
  while (in >> key) {
    if (key == "VmHWM:") {
      uint64_t kb = 0;
      in >> kb;
      return kb * 1024;
    }
    std::string rest;
    std::getline(in, rest);
  }
  return 0;
}

std::string mib(uint64_t bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f MiB", double(bytes) / (1024.0 * 1024.0));
  return buf;
}

struct Row {
  std::string name;
  double seconds = 0;
  uint64_t tiles = 0, peakMerge = 0, coordinatorRss = 0;
  double mergeSeconds = 0;
  bool sameBytes = true;
};

}  // namespace

int main(int argc, char** argv) {
  std::string resolution = "16K", tileSize = "4096";
  for (int i = 1; i + 1 < argc; i += 2) {
    std::string a = argv[i];
    if (a == "--resolution") resolution = argv[i + 1];
    else if (a == "--tile-size") tileSize = argv[i + 1];
    else {
      std::fprintf(stderr, "usage: bench_farm [--resolution 16K] [--tile-size 4096]\n");
      return 2;
    }
  }
  if (argc % 2 == 0) {
    std::fprintf(stderr, "usage: bench_farm [--resolution 16K] [--tile-size 4096]\n");
    return 2;
  }
  fs::path dir = fs::temp_directory_path() / ("cpvs_bench_farm_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  auto path = [&](const std::string& n) { return (dir / n).string(); };

  // The procedural city as an OBJ file: what a client uploads.
  cpvs::Scene city = cpvs::openScene("city");
  {
    std::ofstream obj(path("city.obj"));
    char line[160];
    for (const cpvs::Vec3& p : city.positions) {
      std::snprintf(line, sizeof line, "v %.9g %.9g %.9g\n", p.x, p.y, p.z);
      obj << line;
    }
    for (size_t t = 0; t < city.triangleCount(); ++t)
      obj << "f " << city.indices[3 * t] + 1 << ' ' << city.indices[3 * t + 1] + 1 << ' ' << city.indices[3 * t + 2] + 1
          << '\n';
  }
  const std::string spec = " --sun-elevation 35 --sun-azimuth 30 --resolution " + resolution + " --tile-size " + tileSize;

  std::vector<Row> rows;
  std::fprintf(stderr, "bench_farm: local bake at %s\n", resolution.c_str());
  Ran local = run("'" CPVS_CLI "' bake " + path("city.obj") + spec + " -q --json -o " + path("local.cpvs"));
  if (local.status != 0) {
    std::fprintf(stderr, "local bake failed\n%s", local.out.c_str());
    return 1;
  }
  auto lj = nlohmann::json::parse(local.out.substr(local.out.find('{')));
  rows.push_back({"local (cpvs bake)", local.seconds, lj["tiles"].get<uint64_t>(), 0, 0,
                  lj["stages"].value("merge", 0.0), true});
  const auto localBytes = cpvs::readFile(path("local.cpvs"));

  for (int workers : {1, 2}) {
    std::string name = "farm" + std::to_string(workers);
    ChildProcess server({CPVS_SERVER, "--listen", "127.0.0.1:0", "--data", path(name + ".data"), "--address-file",
                         path(name + ".address")},
                        path(name + ".server.log"));
    std::string address = cpvs::testing::waitForFile(path(name + ".address"), 30);
    std::vector<std::unique_ptr<ChildProcess>> ws;
    for (int w = 0; w < workers; ++w)
      ws.push_back(std::make_unique<ChildProcess>(
          std::vector<std::string>{CPVS_WORKER, "--server", address, "--cache", path(name + ".cache" + std::to_string(w))},
          path(name + ".worker" + std::to_string(w) + ".log")));
    std::fprintf(stderr, "bench_farm: farm with %d worker(s)\n", workers);
    Ran r = run("'" CPVS_CLI "' submit --server " + address + " " + path("city.obj") + spec + " --wait --json --out " +
                path(name + ".cpvs"));
    Row row{std::to_string(workers) + " worker" + (workers > 1 ? "s" : ""), r.seconds};
    if (r.status == 0) {
      auto j = nlohmann::json::parse(r.out.substr(r.out.find('{')));
      row.tiles = j["tiles"].get<uint64_t>();
      row.peakMerge = j["peak_merge_bytes"].get<uint64_t>();
      row.mergeSeconds = j["stages"].value("merge", 0.0);
    } else {
      std::fprintf(stderr, "farm run failed:\n%s\n", r.out.c_str());
    }
    row.coordinatorRss = peakRss(server.pid());
    row.sameBytes = r.status == 0 && cpvs::readFile(path(name + ".cpvs")) == localBytes;
    rows.push_back(row);
    for (auto& w : ws) w->stop(SIGTERM);
    server.stop(SIGTERM);
  }

  char host[64] = "?";
  {
    std::ifstream cpu("/proc/cpuinfo");
    std::string line;
    while (std::getline(cpu, line))
      if (line.rfind("model name", 0) == 0) {
        std::snprintf(host, sizeof host, "%s", line.substr(line.find(':') + 2).c_str());
        break;
      }
  }
  std::time_t now = std::time(nullptr);
  char date[32];
  std::strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
  std::printf("Machine: %s, %u hardware threads; %s\n", host, std::thread::hardware_concurrency(), date);
  std::printf("Scene: procedural city (%zu triangles) as OBJ; %s^3 in %s-texel tiles; all processes on this machine.\n\n",
              city.triangleCount(), resolution.c_str(), tileSize.c_str());
  std::printf("| run | wall s | speedup vs local | tiles | tiles/s | merge s | merge share | peak merge | coordinator peak RSS | same bytes as local |\n");
  std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---|\n");
  for (const Row& r : rows)
    std::printf("| %s | %.2f | %.2fx | %llu | %.2f | %.2f | %.1f %% | %s | %s | %s |\n", r.name.c_str(), r.seconds,
                rows[0].seconds / r.seconds, static_cast<unsigned long long>(r.tiles), double(r.tiles) / r.seconds,
                r.mergeSeconds, 100.0 * r.mergeSeconds / r.seconds, r.peakMerge ? mib(r.peakMerge).c_str() : "-",
                r.coordinatorRss ? mib(r.coordinatorRss).c_str() : "-", r.sameBytes ? "yes" : "NO");
  fs::remove_all(dir);
  return 0;
}
