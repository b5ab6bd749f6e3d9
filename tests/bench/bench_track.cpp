// Sun-track benchmark: a coordinator and one worker (separate processes, this machine)
// and a subscriber (the client library). Per resolution: a place through a day (how many
// keyframes per hour the farm publishes, and bytes per version sent), and a game clock
// (how long before the clock reaches each keyframe's instant its version arrived: the
// lead; negative when the farm falls behind). A program that prints, not a test.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "bench_common.h"
#include "cpvs/base/parse.h"
#include "cpvs/client/farm_client.h"
#include "cpvs/scene/obj_writer.h"
#include "cpvs/scene/source.h"
#include "process_testing.h"

namespace {

namespace fs = std::filesystem;
namespace net = cpvs::net;
using cpvs::testing::ChildProcess;

int64_t wallMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

/// A place through a morning: 8 keyframes half an hour apart.
net::PlacePath morning() {
  net::PlacePath p;
  p.latitudeDeg = 39.742476;
  p.longitudeDeg = -105.1786;
  p.stepSeconds = 1800;
  p.startUtc = "2024-06-21T10:00:00-06:00";
  p.endUtc = "2024-06-21T13:30:00-06:00";
  return p;
}

net::TrackSpec golden(const std::string& hash, const std::string& resolution) {
  net::TrackSpec s;
  s.sceneHash = hash;
  s.resolution = resolution;
  s.keyframesAhead = 2;
  s.path = morning();
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> resolutions{"4K", "16K"};
  double rate = 60, step = 300;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--resolutions") resolutions = cpvs::splitList(argv[i + 1]);
    else if (a == "--rate") rate = std::stod(argv[i + 1]);
    else if (a == "--step") step = std::stod(argv[i + 1]);
    else {
      std::fprintf(stderr, "usage: bench_track [--resolutions 4K,16K] [--rate 60] [--step 300]\n");
      return 2;
    }
  }
  const fs::path dir = fs::temp_directory_path() / ("cpvs_bench_track_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  auto path = [&](const std::string& n) { return (dir / n).string(); };
  cpvs::writeObj(path("city.obj"), cpvs::openScene("city"));

  std::printf("# Sun tracks on a farm\n\n%s, CPU: %s; a coordinator and one worker, this machine\n\n",
              cpvs::bench::now().c_str(), cpvs::bench::cpuModel().c_str());
  std::printf("| R | track | versions | seconds | keyframes per hour | mean bytes per version | clock lead, first / mean / last s |\n");
  std::printf("|---|---|---:|---:|---:|---:|---|\n");
  for (const std::string& resolution : resolutions) {
    const std::string name = "farm-" + resolution;
    ChildProcess server({CPVS_SERVER, "--listen", "127.0.0.1:0", "--data", path(name + ".data"), "--address-file",
                         path(name + ".address")},
                        path(name + ".server.log"));
    const std::string address = cpvs::testing::waitForFile(path(name + ".address"), 30);
    ChildProcess worker({CPVS_WORKER, "--server", address, "--cache", path(name + ".cache")}, path(name + ".worker.log"));
    cpvs::client::FarmClient client(cpvs::net::Connection{address, "", ""});
    const std::string hash = client.uploadScene(path("city.obj")).sceneHash;

    // A place through a morning: throughput.
    const auto start = std::chrono::steady_clock::now();
    const net::TrackStatus day = client.createTrack("day-" + resolution, golden(hash, resolution));
    uint64_t versions = 0, bytes = 0;
    client.subscribe(day.trackId, 0, [&](const net::TrackVersion&, const std::vector<uint8_t>& b) {
      ++versions;
      bytes += b.size();
      return true;
    });
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("| %s | place, 8 keyframes 30 min apart | %llu | %.1f | %.0f | %.2f MiB | - |\n", resolution.c_str(),
                static_cast<unsigned long long>(versions), seconds, double(versions) / seconds * 3600,
                double(bytes) / versions / (1 << 20));
    std::fflush(stdout);

    // A game clock: how far ahead of it the versions arrive (the first is baked at creation).
    net::TrackSpec clock = golden(hash, resolution);
    net::PlacePath place = morning();
    place.endUtc = "";
    place.stepSeconds = step;
    clock.path = net::ClockPath{place, rate};
    const net::TrackStatus followed = client.createTrack("clock-" + resolution, clock);
    std::vector<double> leads;
    client.subscribe(followed.trackId, 0, [&](const net::TrackVersion& v, const std::vector<uint8_t>&) {
      const double due = double(followed.createdUnixMs) + double(v.keyframe) * step / rate * 1000;
      leads.push_back((due - double(wallMs())) / 1000);
      return leads.size() < 6;
    });
    client.cancelTrack(followed.trackId);
    double mean = 0;
    for (double l : leads) mean += l / double(leads.size());
    std::printf("| %s | clock x%g, a keyframe every %g s of game time (%.1f s real) | %zu | - | - | - | %.1f / %.1f / %.1f |\n",
                resolution.c_str(), rate, step, step / rate, leads.size(), leads.front(), mean, leads.back());
    std::fflush(stdout);
    worker.stop(SIGTERM);
    server.stop(SIGTERM);
  }
  std::printf("\nclock lead: the real time left before the game clock reached the keyframe's instant when its version\n"
              "arrived (negative: it arrived late). The clock's first keyframe is the clock's time at creation; here it is\n"
              "also the place track's first (the same sun), so it is that keyframe's job, already baked.\n");
  fs::remove_all(dir);
  return 0;
}
