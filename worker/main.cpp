// `cpvs-worker`: bakes tiles for a CPVS bake farm.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <atomic>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <thread>

#include "cpvs/base/vec3.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/error.h"
#include "cpvs/base/file.h"
#include "cpvs/metrics/checks.h"
#include "cpvs/metrics/endpoint.h"
#include "cpvs/net/connection.h"
#include "tile_worker.h"

namespace {

cpvs::worker::TileWorker* gWorker = nullptr;
std::atomic<int> gSignals{0};

void onSignal(int) {
  // First signal: finish the tiles in progress (the drain); second: give them back and
  // leave (the drain watcher does that, outside the handler).
  if (gWorker && ++gSignals == 1) gWorker->stop();
}

std::string trimmed(std::string s) {
  // Tokens often come from files or secrets with a trailing newline.
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  return s;
}

// A comparison whose time does not say how much of a guess matched (only its length).
bool sameToken(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  unsigned char diff = 0;
  for (size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

std::string readToken(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw cpvs::InputError("cannot read the metrics token file " + path);
  std::string token;
  std::getline(in, token);
  token = trimmed(token);
  if (token.empty()) throw cpvs::InputError("the metrics token file " + path + " is empty");
  return token;
}

// `cpvs-worker --check`: whether this machine's worker is alive and can work, for a
// liveness probe or a person: the coordinator answered it within `maxSilence` seconds (its
// cache's alive file), its cache takes files and has room, its certificates are valid.
int checkWorker(const cpvs::worker::WorkerConfig& config, double maxSilence, double minFreeMb,
                const std::string& metricsTlsCert) {
  namespace fs = std::filesystem;
  cpvs::metrics::Checks checks;
  std::error_code ec;
  const auto touched = fs::last_write_time(cpvs::worker::alivePath(config.cacheDir), ec);
  if (ec) {
    checks.check(false, "the coordinator has not answered this worker yet (no " +
                            cpvs::worker::alivePath(config.cacheDir) + ")");
  } else {
    const double age = std::chrono::duration<double>(fs::file_time_type::clock::now() - touched).count();
    checks.check(age <= maxSilence, "the coordinator answered this worker " + std::to_string(int(age)) +
                                        " s ago (at most " + std::to_string(int(maxSilence)) + " s wanted)");
  }
  checks.folderWritable(config.cacheDir);
  checks.freeSpace(config.cacheDir, uint64_t(minFreeMb * 1024 * 1024));
  if (!config.server.caFile.empty()) checks.certificate(config.server.caFile, "CA");
  if (!metricsTlsCert.empty()) checks.certificate(metricsTlsCert, "metrics TLS");
  return checks.finish();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"cpvs-worker: leases tiles from a CPVS bake farm coordinator, bakes their sub-DAGs and returns them. "
               "SIGTERM once: finish the tiles in progress and stop (the drain, at most --drain-seconds); twice, or "
               "when the drain's time is up: give them back to the coordinator at once and stop."};
  cpvs::worker::WorkerConfig config;
  config.slots = 1;
  config.cacheDir = "/tmp/cpvs-worker-cache";
  char host[256] = "worker";
  gethostname(host, sizeof host - 1);
  config.workerId = std::string(host) + ":" + std::to_string(getpid());
  app.add_option("--server", config.server.address, "Coordinator HOST:PORT (required but with --check)");
  app.add_option("--slots", config.slots, "Tiles baked at once")->capture_default_str()->check(CLI::Range(1, 256));
  app.add_option("--cache", config.cacheDir, "Folder for fetched scenes (and baked tiles, in tiles/)")->capture_default_str();
  app.add_option("--tile-cache-mb", config.tileCacheMb,
                 "MiB of baked tiles kept under the content that decides them, so that a tile leased again (an "
                 "edited scene's unchanged tiles, a resubmitted bake) is sent without baking; least recently used "
                 "out; 0: none")
      ->capture_default_str();
  app.add_option("--token", config.server.token, "Bearer token (default: $CPVS_TOKEN)");
  app.add_option("--ca", config.server.caFile, "PEM roots to trust: use TLS");
  app.add_option("--cert", config.server.certFile,
                 "PEM client certificate to present (with --key and --ca): the worker's own identity for a coordinator "
                 "with --worker-ca, instead of a token");
  app.add_option("--key", config.server.keyFile, "PEM private key of --cert");
  app.add_flag("--allow-plaintext-token", config.server.allowPlaintextToken,
               "Send the token without TLS to a coordinator that is not on this machine (a trusted private network)");
  app.add_option("--id", config.workerId, "Name in the coordinator's logs")->capture_default_str();
  app.add_option("--max-tiles", config.maxTiles, "Stop after this many tiles (0 = run until stopped)");
  double importMemoryMb = double(config.import.memoryBytes >> 20);
  app.add_option("--import-memory-mb", importMemoryMb,
                 "Address space of cpvs-import, which imports each fetched scene (give what the coordinator's "
                 "--import-memory-mb is: a scene it took must import here too)")
      ->capture_default_str()->check(CLI::Range(64.0, 1048576.0));
  app.add_option("--import-seconds", config.import.seconds, "Longest one scene's import may take (as the coordinator's)")
      ->capture_default_str()->check(CLI::Range(1.0, 86400.0));
  app.add_option("--threads,-j", config.threads,
                 "Threads for all the slots' bakes together, for a worker sharing its machine (0 = all cores)")
      ->capture_default_str()
      ->check(CLI::Range(0, 4096));
  std::string metricsListen, metricsTokenFile, metricsTlsCert, metricsTlsKey, metricsAddressFile;
  double drainSeconds = 0;
  bool metricsOpen = false, check = false;
  double maxSilence = 600, minFreeMb = 1024;
  app.add_flag("--check", check,
               "Check the worker this command line describes and exit (0 alive, 1 not): the coordinator answered it "
               "within --max-silence, --cache takes files and has --min-free-mb, its certificates are valid. For "
               "liveness probes");
  app.add_option("--max-silence", maxSilence, "With --check: the most seconds since the coordinator last answered")
      ->capture_default_str();
  app.add_option("--min-free-mb", minFreeMb, "With --check: the least free space in --cache")->capture_default_str();
  app.add_option("--drain-seconds", drainSeconds,
                 "After SIGTERM, how long tiles in progress may take before they are given back (0 = as long as "
                 "they take); set it below the pod's termination grace period")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 86400.0));
  app.add_option("--metrics", metricsListen, "HOST:PORT to serve Prometheus metrics on (GET /metrics; port 0 picks one)");
  app.add_option("--metrics-token-file", metricsTokenFile,
                 "File with the bearer token a scrape must present (the coordinator's metrics token)");
  app.add_option("--metrics-tls-cert", metricsTlsCert, "PEM certificate chain: serve the metrics over HTTPS");
  app.add_option("--metrics-tls-key", metricsTlsKey, "PEM private key of --metrics-tls-cert");
  app.add_option("--metrics-address-file", metricsAddressFile, "Write the metrics HOST:PORT served to this file");
  app.add_flag("--metrics-open", metricsOpen,
               "Serve metrics on an address other than loopback without --metrics-token-file");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (config.server.token.empty())
    if (const char* t = std::getenv("CPVS_TOKEN")) config.server.token = t;
  config.server.token = trimmed(config.server.token);
  if (check) return checkWorker(config, maxSilence, minFreeMb, metricsTlsCert);
  if (config.server.certFile.empty() != config.server.keyFile.empty() ||
      (!config.server.certFile.empty() && config.server.caFile.empty())) {
    std::fprintf(stderr, "give --cert and --key together, with --ca\n");
    return 2;
  }
  if (config.server.address.empty()) {
    std::fprintf(stderr, "--server is required\nRun with --help for more information.\n");
    return 2;
  }
  spdlog::set_pattern("[%Y-%m-%d %H:%M:%S.%e] [worker] [%l] %v");
  std::unique_ptr<tbb::global_control> threadLimit;
  if (config.threads > 0)
    threadLimit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, config.threads);
  try {
    config.import.helper = cpvs::requiredImportProgram("cpvs-worker");
    config.import.memoryBytes = uint64_t(importMemoryMb * 1024 * 1024);
    cpvs::worker::TileWorker worker(config);
    std::unique_ptr<cpvs::metrics::Endpoint> metrics;
    if (!metricsListen.empty()) {
      cpvs::metrics::EndpointOptions options{metricsListen, metricsTlsCert, metricsTlsKey, {}};
      if (!metricsTokenFile.empty()) {
        options.authorize = [token = readToken(metricsTokenFile)](const std::string& presented) {
          return sameToken(presented, token);
        };
      } else if (!cpvs::net::isLoopbackAddress(metricsListen) && !metricsOpen) {
        throw cpvs::InputError("refusing to serve metrics on " + metricsListen +
                               " without --metrics-token-file (or give --metrics-open)");
      }
      if (!metricsTokenFile.empty() && metricsTlsCert.empty() && !cpvs::net::isLoopbackAddress(metricsListen) &&
          !config.server.allowPlaintextToken)
        throw cpvs::InputError("refusing to take the metrics token in plaintext on " + metricsListen +
                               ": give --metrics-tls-cert and --metrics-tls-key, or --allow-plaintext-token");
      metrics = std::make_unique<cpvs::metrics::Endpoint>(options, worker.metrics().registry(),
                                                          [&worker] { worker.metrics().refresh(); });
      if (!metricsAddressFile.empty()) {
        const std::string text = metrics->address() + "\n";
        cpvs::writeFileAtomic(metricsAddressFile, std::vector<uint8_t>(text.begin(), text.end()));
      }
      spdlog::info("metrics on {}://{}/metrics", metricsTlsCert.empty() ? "http" : "https", metrics->address());
    }
    gWorker = &worker;
    std::signal(SIGTERM, onSignal);
    std::signal(SIGINT, onSignal);
    spdlog::info("{} pulling tiles from {} with {} slot(s), {} thread(s)", config.workerId, config.server.address,
                 config.slots, config.threads > 0 ? std::to_string(config.threads) : std::string("all"));
    // The drain's watcher: a second signal, or the drain's time up, gives the tiles in
    // progress back and ends the process without waiting for their bakes.
    std::atomic<bool> finished{false};
    std::thread watcher([&] {
      std::optional<std::chrono::steady_clock::time_point> drainEnds;
      while (!finished) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        const int signals = gSignals;
        if (signals == 0) continue;
        if (!drainEnds) {
          drainEnds = std::chrono::steady_clock::now() + std::chrono::milliseconds(int64_t(drainSeconds * 1000));
          spdlog::info("draining: no new tiles; those in progress finish{}",
                       drainSeconds > 0 ? " within " + std::to_string(int(drainSeconds)) + " s" : std::string());
        }
        if (signals >= 2 || (drainSeconds > 0 && std::chrono::steady_clock::now() >= *drainEnds)) {
          const size_t n = worker.releaseInFlight();
          spdlog::info("{}: gave {} tile(s) in progress back; stopping after {} tile(s)",
                       signals >= 2 ? "second signal" : "drain time up", n, worker.tilesDone());
          std::fflush(nullptr);
          std::_Exit(0);
        }
      }
    });
    worker.run();
    finished = true;
    watcher.join();
    spdlog::info("stopped after {} tile(s)", worker.tilesDone());
    return 0;
  } catch (const cpvs::InputError& e) {
    spdlog::error("{}", e.what());
    return 2;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 3;
  }
}
