// `cpvs-worker`: bakes tiles for a CPVS bake farm.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <atomic>
#include <cctype>
#include <csignal>
#include <cstdlib>
#include <memory>
#include <thread>

#include "cpvs/base/vec3.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/error.h"
#include "tile_worker.h"

namespace {

cpvs::worker::TileWorker* gWorker = nullptr;
std::atomic<int> gSignals{0};

void onSignal(int) {
  // First signal: finish the tiles in progress; second: release them and leave.
  if (gWorker) (++gSignals == 1) ? gWorker->stop() : gWorker->abandon();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"cpvs-worker: leases tiles from a CPVS bake farm coordinator, bakes their sub-DAGs and returns them. "
               "SIGTERM once: finish the tiles in progress and stop; twice: release them and stop."};
  cpvs::worker::WorkerConfig config;
  config.slots = 1;
  config.cacheDir = "/tmp/cpvs-worker-cache";
  char host[256] = "worker";
  gethostname(host, sizeof host - 1);
  config.workerId = std::string(host) + ":" + std::to_string(getpid());
  app.add_option("--server", config.server.address, "Coordinator HOST:PORT")->required();
  app.add_option("--slots", config.slots, "Tiles baked at once")->capture_default_str()->check(CLI::Range(1, 256));
  app.add_option("--cache", config.cacheDir, "Folder for fetched scenes")->capture_default_str();
  app.add_option("--token", config.server.token, "Bearer token (default: $CPVS_TOKEN)");
  app.add_option("--ca", config.server.caFile, "PEM roots to trust: use TLS");
  app.add_flag("--allow-plaintext-token", config.server.allowPlaintextToken,
               "Send the token without TLS to a coordinator that is not on this machine (a trusted private network)");
  app.add_option("--id", config.workerId, "Name in the coordinator's logs")->capture_default_str();
  app.add_option("--max-tiles", config.maxTiles, "Stop after this many tiles (0 = run until stopped)");
  app.add_option("--threads,-j", config.threads,
                 "Threads for all the slots' bakes together, for a worker sharing its machine (0 = all cores)")
      ->capture_default_str()
      ->check(CLI::Range(0, 4096));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (config.server.token.empty())
    if (const char* t = std::getenv("CPVS_TOKEN")) config.server.token = t;
  // Tokens often come from files or secrets with a trailing newline.
  while (!config.server.token.empty() && std::isspace(static_cast<unsigned char>(config.server.token.back())))
    config.server.token.pop_back();
  spdlog::set_pattern("[%Y-%m-%d %H:%M:%S.%e] [worker] [%l] %v");
  std::unique_ptr<tbb::global_control> threadLimit;
  if (config.threads > 0)
    threadLimit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, config.threads);
  try {
    cpvs::worker::TileWorker worker(config);
    gWorker = &worker;
    std::signal(SIGTERM, onSignal);
    std::signal(SIGINT, onSignal);
    spdlog::info("{} pulling tiles from {} with {} slot(s), {} thread(s)", config.workerId, config.server.address,
                 config.slots, config.threads > 0 ? std::to_string(config.threads) : std::string("all"));
    worker.run();
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
