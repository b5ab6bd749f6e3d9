// Capacity of one coordinator: the real `cpvs-server` against N fake workers in this
// process that lease tiles and return precomputed sub-DAGs at once (no baking), so that
// only the coordinator's share of the work is timed: leases, receiving and validating
// results, writing them, merging them and writing the artifact. For each resolution and
// worker count it prints leases per second (to the last result), merged megabytes per
// second (to the artifact, its merge's tail included), the p50 and p99
// latency of LeaseTile and CompleteTile as the workers saw them, and the coordinator's
// CPU (cores busy) and peak resident memory; then, from the best rate and the seconds a
// real 4K tile takes to bake here, how many real workers one coordinator keeps busy.
//
// The returned sub-DAGs are real: a few distinct tiles of the scene baked once (--distinct),
// each returned for many tiles with its roots moved to the leased tile. The merge thus
// shares more nodes than a real bake's would; the rest of the coordinator's work per tile
// (bytes, checks, disk) is the real one. The fake workers run on the same cores as the
// coordinator: on a small machine they take part of its CPU.
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "bench_common.h"
#include "cpvs/bake/bake.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/tile_plan.h"
#include "cpvs/base/hash.h"
#include "cpvs/io/sub_dag_file.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/net/channel.h"
#include "cpvs/net/chunked_stream.h"
#include "cpvs/scene/obj_writer.h"
#include "cpvs/v1/farm.grpc.pb.h"
#include "process_testing.h"

namespace {

namespace fs = std::filesystem;
namespace pb = cpvs::v1;
using Clock = std::chrono::steady_clock;

struct Args : cpvs::bench::CommonArgs {
  std::vector<int> workers{1, 4, 16};
  int distinct = 8;
};

/// Utime + stime of a process in seconds, and its resident bytes now.
struct ProcessSample {
  double cpuSeconds = 0;
  uint64_t rss = 0;
};

ProcessSample sample(pid_t pid) {
  ProcessSample s;
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  std::getline(stat, line);
  const size_t close = line.rfind(')');
  if (close == std::string::npos) return s;
  std::istringstream rest(line.substr(close + 2));
  std::vector<std::string> f;
  for (std::string w; rest >> w;) f.push_back(w);
  if (f.size() > 21) {
    const double tick = double(sysconf(_SC_CLK_TCK));
    s.cpuSeconds = (std::stod(f[11]) + std::stod(f[12])) / tick;
    s.rss = uint64_t(std::stoull(f[21])) * uint64_t(sysconf(_SC_PAGESIZE));
  }
  return s;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(p * double(v.size())))];
}

struct Run {
  int workers = 0;
  uint64_t tiles = 0, bytes = 0;
  double seconds = 0, resultSeconds = 0, leaseP50 = 0, leaseP99 = 0, completeP50 = 0, completeP99 = 0, cores = 0;
  uint64_t peakRss = 0;
};

/// The job's status through ListJobs (there is no single-job read for clients).
std::optional<pb::JobStatus> jobByRequest(pb::Farm::Stub& farm, const std::string& requestId) {
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  pb::ListJobsRequest req;
  req.set_include_finished(true);
  req.set_page_size(1000);
  pb::ListJobsReply reply;
  if (!farm.ListJobs(&ctx, req, &reply).ok()) return std::nullopt;
  for (const auto& j : reply.jobs())
    if (j.request_id() == requestId) return j;
  return std::nullopt;
}

Run runWorkers(const std::string& address, pid_t coordinator, const std::string& requestId, int n,
               const std::vector<std::vector<uint8_t>>& encoded) {
  cpvs::net::Connection c{address, "", ""};
  auto farm = pb::Farm::NewStub(cpvs::net::makeChannel(c));
  std::optional<pb::JobStatus> job;
  for (int i = 0; i < 600 && !(job = jobByRequest(*farm, requestId)); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  if (!job) throw std::runtime_error("the coordinator does not list job " + requestId);
  const uint64_t expected = job->tiles_total() - job->tiles_untouched() - job->tiles_unread();

  std::atomic<uint64_t> completed{0}, bytes{0};
  std::atomic<bool> done{false};
  std::mutex latencyMutex;
  std::vector<double> leaseMs, completeMs;
  std::atomic<uint64_t> peakRss{0};
  const ProcessSample before = sample(coordinator);
  const auto start = Clock::now();
  std::thread monitor([&] {
    while (!done) {
      peakRss = std::max<uint64_t>(peakRss, sample(coordinator).rss);
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  });
  std::vector<std::thread> threads;
  for (int w = 0; w < n; ++w) {
    threads.emplace_back([&, w] {
      auto stub = pb::Workers::NewStub(cpvs::net::makeChannel(c));
      std::vector<double> myLease, myComplete;
      while (!done) {
        pb::LeaseRequest req;
        req.set_worker_id("fake-" + std::to_string(w));
        pb::TileLease lease;
        grpc::ClientContext ctx;
        auto t0 = Clock::now();
        if (!stub->LeaseTile(&ctx, req, &lease).ok()) break;
        myLease.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
        if (!lease.granted()) {
          if (completed >= expected) break;
          std::this_thread::sleep_for(std::chrono::milliseconds(20));
          continue;
        }
        const std::vector<uint8_t>& result = encoded.at(lease.tile_index());
        grpc::ClientContext cctx;
        pb::CompleteReply reply;
        t0 = Clock::now();
        auto writer = stub->CompleteTile(&cctx, &reply);
        cpvs::net::sendChunks<pb::TileResultChunk>(
            cpvs::net::ChunkSource::ofBytes(result.data(), result.size()), 0, *writer,
            [&](pb::TileResultChunk& chunk, uint64_t, bool first) {
              if (!first) return;
              chunk.set_lease_id(lease.lease_id());
              chunk.set_total_size(result.size());
              chunk.set_checksum(cpvs::contentHash(result.data(), result.size()).hex());
            });
        writer->WritesDone();
        const grpc::Status s = writer->Finish();
        myComplete.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
        if (!s.ok()) {
          std::fprintf(stderr, "bench_capacity: CompleteTile: %s\n", s.error_message().c_str());
          break;
        }
        bytes += result.size();
        ++completed;
      }
      std::lock_guard lock(latencyMutex);
      leaseMs.insert(leaseMs.end(), myLease.begin(), myLease.end());
      completeMs.insert(completeMs.end(), myComplete.begin(), myComplete.end());
    });
  }
  for (auto& t : threads) t.join();
  const double resultSeconds = std::chrono::duration<double>(Clock::now() - start).count();
  // The run ends when the artifact is written: the merge's tail is the coordinator's too.
  for (;;) {
    job = jobByRequest(*farm, requestId);
    if (!job || job->state() == pb::JOB_DONE || job->state() == pb::JOB_FAILED) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  Run r;
  r.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  done = true;
  monitor.join();
  if (!job || job->state() != pb::JOB_DONE)
    throw std::runtime_error("job " + requestId + " did not finish: " + (job ? job->error() : "gone"));
  r.workers = n;
  r.resultSeconds = resultSeconds;
  r.tiles = completed;
  r.bytes = bytes;
  r.leaseP50 = percentile(leaseMs, 0.5);
  r.leaseP99 = percentile(leaseMs, 0.99);
  r.completeP50 = percentile(completeMs, 0.5);
  r.completeP99 = percentile(completeMs, 0.99);
  r.cores = (sample(coordinator).cpuSeconds - before.cpuSeconds) / r.seconds;
  r.peakRss = peakRss;
  return r;
}

int run(int argc, char** argv) {
  using namespace cpvs;
  Args a;
  a.scenes = {"city"};
  a.log2Resolutions = {14, 16, 18};
  bench::parseBenchArgs(argc, argv, a, [&](const std::string& option, const std::string& value) {
    if (option == "--workers") {
      a.workers.clear();
      std::stringstream list(value);
      for (std::string w; std::getline(list, w, ',');) a.workers.push_back(bench::parsePositive(w, "--workers"));
      return true;
    }
    if (option == "--distinct") {
      a.distinct = bench::parsePositive(value, "--distinct");
      return true;
    }
    return false;
  });
  if (a.help) {
    std::printf("usage: bench_capacity [--resolutions 16K,64K,256K] [--workers 1,4,16] [--scene city] "
                "[--distinct 8] [--sun-dir X,Y,Z]\n");
    return 0;
  }
  std::vector<std::string> notes;
  auto scene = bench::openBenchScene(a.scenes.at(0), "bench_capacity", notes);
  if (!scene) return 2;
  const fs::path dir = fs::temp_directory_path() / ("cpvs_bench_capacity_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  writeObj((dir / "scene.obj").string(), scene->scene);
  const std::string sun = bench::format("%.17g", a.sunDir.x) + "," + bench::format("%.17g", a.sunDir.y) + "," +
                          bench::format("%.17g", a.sunDir.z);

  testing::ChildProcess coordinator({CPVS_SERVER, "--listen", "127.0.0.1:0", "--data", (dir / "data").string(),
                                     "--address-file", (dir / "address").string(), "--max-tiles-per-job", "65536"},
                                    (dir / "coordinator.log").string());
  const std::string address = testing::waitForFile((dir / "address").string(), 30);
  if (address.empty()) throw std::runtime_error("the coordinator did not start: " + coordinator.log());

  std::printf("# One coordinator's capacity\n\n%s, CPU: %s, %u cores shared by the coordinator and the fake "
              "workers; scene %s, 4K tiles, %d distinct real tiles returned\n\n",
              bench::now().c_str(), bench::cpuModel().c_str(), std::thread::hardware_concurrency(),
              scene->label.c_str(), a.distinct);
  std::printf("| R | tiles | fake workers | seconds to the last result / to the artifact | leases/s | merged MB/s | LeaseTile p50 / p99 ms | "
              "CompleteTile p50 / p99 ms | coordinator cores | coordinator peak RSS |\n");
  std::printf("|---|---:|---:|---:|---:|---:|---|---|---:|---:|\n");
  std::fflush(stdout);
  struct Capacity {
    int log2R;
    double tilesPerSecond, secondsPerTile;
    uint64_t tileBytes;
  };
  std::vector<Capacity> capacity;
  BakeOptions options;  // the farm's defaults, as `cpvs submit` sends them
  for (int log2R : a.log2Resolutions) {
    const TilePlan plan(log2R, options.log2TileSize);
    const OrthoGrid grid = makeGrid(scene->scene, LightFrame::fromDirection(a.sunDir), log2R);
    BakeScene prepared(scene->scene, grid, options.renderer, a.threads);
    // A few real tiles, spread over those the scene touches; each baked once (timed: the
    // seconds a real worker spends on a tile here).
    std::vector<Dag> real;
    double bakeSeconds = 0;
    const uint64_t count = plan.count();
    for (uint64_t i = 0; i < count && int(real.size()) < a.distinct; i += std::max<uint64_t>(1, count / uint64_t(a.distinct * 4))) {
      const TileCoord t = plan.tile(i);
      if (!prepared.touchesTile(t.x, t.y, plan.log2TileSize())) continue;
      const auto t0 = Clock::now();
      real.push_back(bakeTile(prepared, t.x, t.y, options));
      bakeSeconds += std::chrono::duration<double>(Clock::now() - t0).count();
    }
    if (real.empty()) throw std::runtime_error("the scene touches no tile at " + bench::resolutionLabel(log2R));
    // Every tile's result encoded before the clock starts: a real tile's nodes under the
    // leased tile's roots.
    std::vector<std::vector<uint8_t>> encoded(count);
    uint64_t encodedBytes = 0;
    for (uint64_t i = 0; i < count; ++i) {
      const TileCoord t = plan.tile(i);
      Dag d = real[(t.x * 7 + t.y * 13) % real.size()];
      for (size_t z = 0; z < d.roots.size(); ++z) d.roots[z].key = rootKey(t.x, t.y, z);
      encoded[i] = encodeSubDag(d, true);
      encodedBytes += encoded[i].size();
    }
    double best = 0;
    for (int n : a.workers) {
      const std::string requestId = "capacity-" + std::to_string(log2R) + "-" + std::to_string(n);
      testing::CommandResult submitted = testing::runShell(
          "'" CPVS_CLI "' submit --server " + address + " '" + (dir / "scene.obj").string() + "' --sun-dir " + sun +
          " --resolution " + bench::resolutionLabel(log2R) + " --request-id " + requestId + " 2>&1");
      if (submitted.status != 0) throw std::runtime_error("cpvs submit: " + submitted.out);
      const Run r = runWorkers(address, coordinator.pid(), requestId, n, encoded);
      best = std::max(best, double(r.tiles) / r.resultSeconds);
      std::printf("| %s | %llu | %d | %.2f / %.2f | %.1f | %.1f | %.1f / %.1f | %.1f / %.1f | %.2f | %s |\n",
                  bench::resolutionLabel(log2R).c_str(), static_cast<unsigned long long>(r.tiles), n, r.resultSeconds,
                  r.seconds, double(r.tiles) / r.resultSeconds, double(r.bytes) / 1e6 / r.seconds, r.leaseP50, r.leaseP99, r.completeP50,
                  r.completeP99, r.cores, bench::humanBytes(r.peakRss).c_str());
      std::fflush(stdout);
    }
    capacity.push_back({log2R, best, bakeSeconds / double(real.size()), encodedBytes / count});
  }
  std::printf("\n| R | best leases/s | a real 4K tile's bake here, s | mean result bytes | real workers one "
              "coordinator keeps busy |\n|---|---:|---:|---:|---:|\n");
  for (const Capacity& c : capacity)
    std::printf("| %s | %.1f | %.3f | %s | %.0f |\n", bench::resolutionLabel(c.log2R).c_str(), c.tilesPerSecond,
                c.secondsPerTile, bench::humanBytes(c.tileBytes).c_str(), c.tilesPerSecond * c.secondsPerTile);
  std::printf("\nA real worker here bakes a tile in the seconds above with every core of this machine; one "
              "coordinator keeps busy as many as its best rate times those seconds.\n");
  for (const std::string& n : notes) std::printf("%s\n", n.c_str());
  coordinator.stop(SIGTERM);
  fs::remove_all(dir);
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return cpvs::bench::benchMain("bench_capacity", run, argc, argv); }
