// `cpvs-server`: the bake farm's coordinator.
#include <CLI/CLI.hpp>
#include <grpcpp/grpcpp.h>
#include <grpcpp/security/tls_certificate_provider.h>
#include <grpcpp/security/tls_credentials_options.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "coordinator/coordinator.h"
#include "cpvs/scene/isolated_import.h"
#include "cpvs/base/error.h"
#include "cpvs/base/file.h"
#include "cpvs/base/parse.h"
#include "cpvs/metrics/checks.h"
#include "cpvs/metrics/endpoint.h"
#include "cpvs/net/health.h"
#include "cpvs/net/connection.h"
#include "rpc/auth.h"
#include "rpc/farm_server.h"

namespace {

std::atomic<bool> gStop{false};

void onSignal(int) { gStop = true; }

// `cpvs-server --check`: whether the coordinator serving `listen` from `data` is ready, for
// a readiness probe or a person: it answers on its port (over its TLS), its store takes
// writes, its leases move, its data folder takes files and has room, its certificate is
// valid. Prints a line a finding; 0 when nothing failed.
int checkCoordinator(const std::string& listen, const std::string& data, const std::string& tlsCert,
                     const std::string& ca, double minFreeMb) {
  cpvs::metrics::Checks checks;
  // The coordinator's own port, from this machine: a wildcard address is reached on loopback.
  std::string host = listen.substr(0, listen.rfind(':'));
  const std::string port = listen.substr(listen.rfind(':') + 1);
  if (host == "0.0.0.0" || host.empty()) host = "127.0.0.1";
  if (host == "[::]") host = "[::1]";
  cpvs::net::Connection c{host + ":" + port, "", ""};
  if (!tlsCert.empty()) {
    c.caFile = ca.empty() ? tlsCert : ca;  // a self-signed certificate is its own root
    c.tlsName = cpvs::metrics::certificateName(tlsCert);
  }
  const std::string store = cpvs::net::healthOf(c, "", 5);
  checks.check(store == "SERVING", "the coordinator on " + c.address + (tlsCert.empty() ? "" : " (TLS)") +
                                       (store == "SERVING" ? " answers; its job store takes writes"
                                                           : " is not ready: " + store));
  if (store == "SERVING" || store == "NOT_SERVING") {
    const std::string leases = cpvs::net::healthOf(c, cpvs::server::kLeasesHealth, 5);
    checks.check(leases == "SERVING", leases == "SERVING" ? "leases move (the reaper ran within 10 s)"
                                                          : "leases do not move: " + leases);
  }
  checks.folderWritable(data);
  checks.freeSpace(data, uint64_t(minFreeMb * 1024 * 1024));
  if (!tlsCert.empty()) checks.certificate(tlsCert, "TLS");
  if (!ca.empty()) checks.certificate(ca, "CA");
  return checks.finish();
}

std::string readText(const std::string& path, const char* what) {
  std::ifstream in(path);
  if (!in) throw cpvs::InputError(std::string("cannot read the ") + what + " " + path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

int main(int argc, char** argv) {
  // The coordinator runs itself in this mode to import an upload in a limited child
  // process (cpvs/scene/isolated_import.h); not for people.
  CLI::App app{"cpvs-server: the coordinator of a CPVS bake farm. Takes bake jobs, splits them into tiles, "
               "leases them to workers, merges their sub-DAGs as they arrive and serves the artifacts."};
  std::string listen = "127.0.0.1:7443", data, addressFile, tokensFile, tlsCert, tlsKey, metricsListen, metricsAddressFile;
  cpvs::server::CoordinatorConfig config;
  std::string maxResolution = "256K";
  double maxUploadMb = 4096;
  bool insecureOpen = false, allowPlaintextTokens = false, check = false;
  std::string checkCa;
  double minFreeMb = 1024;
  double importMemoryMb = 8192;
  app.add_option("--listen", listen, "HOST:PORT to serve on; port 0 picks a free port")->capture_default_str();
  app.add_option("--data", data, "Folder for the job database, scenes, tile results and artifacts")->required();
  app.add_option("--address-file", addressFile,
                 "Write the bound HOST:PORT here once serving (an old file there is removed at start)");
  app.add_option("--tokens", tokensFile, "Bearer tokens, lines 'ROLE TOKEN' (client, worker, admin); none = open");
  app.add_option("--tls-cert", tlsCert, "PEM certificate chain: serve TLS (with --tls-key)");
  app.add_option("--tls-key", tlsKey, "PEM private key of --tls-cert");
  std::string workerCa;
  int tlsReloadSeconds = 60;
  app.add_option("--worker-ca", workerCa,
                 "PEM CA whose client certificates make workers (mTLS, with --tls-*): such a worker needs no token");
  app.add_option("--tls-reload-seconds", tlsReloadSeconds,
                 "How often the certificate, key and --worker-ca files are read again: a rotated certificate is served "
                 "without a restart")
      ->capture_default_str()
      ->check(CLI::Range(1, 86400));
  app.add_flag("--insecure-open", insecureOpen,
               "Serve an address other than loopback without --tokens: anyone who reaches it may do anything");
  app.add_flag("--allow-plaintext-tokens", allowPlaintextTokens,
               "Take --tokens without TLS on an address other than loopback (a private network you trust)");
  app.add_option("--metrics", metricsListen,
                 "HOST:PORT to serve Prometheus metrics on (GET /metrics; port 0 picks one): HTTPS with --tls-*, and "
                 "with --tokens only for metrics and admin tokens");
  app.add_option("--metrics-address-file", metricsAddressFile, "Write the metrics HOST:PORT served to this file");
  app.add_flag("--check", check,
               "Check the coordinator this command line describes and exit (0 ready, 1 not): it answers on "
               "--listen, its store takes writes, leases move, --data takes files and has --min-free-mb, "
               "its certificate is valid. For readiness probes");
  app.add_option("--ca", checkCa, "With --check and --tls-cert: the CA that signed it (default: the certificate itself)");
  app.add_option("--min-free-mb", minFreeMb, "With --check: the least free space in --data")->capture_default_str();
  cpvs::server::AuthLimits authLimits;
  app.add_option("--auth-failure-limit", authLimits.limit,
                 "Failed authentications of one address within a minute before it is refused for "
                 "--auth-lockout-seconds (0: no limit)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000000));
  app.add_option("--auth-lockout-seconds", authLimits.lockoutSeconds, "How long an address is refused after that")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 86400.0));
  cpvs::server::ConnectionLimits connections;
  app.add_option("--max-streams-per-connection", connections.streamsPerConnection,
                 "Calls open at once on one client connection; more wait for a place")
      ->capture_default_str()->check(CLI::Range(1, 100000));
  app.add_option("--idle-connection-seconds", connections.idleSeconds,
                 "A connection with no call open this long is closed (the client reconnects when it calls)")
      ->capture_default_str()->check(CLI::Range(1.0, 7 * 86400.0));
  app.add_option("--keepalive-seconds", connections.keepaliveSeconds,
                 "A connection with calls open is pinged this often; one that does not answer within "
                 "--keepalive-timeout-seconds is closed and its calls end (their watch places come back)")
      ->capture_default_str()->check(CLI::Range(1.0, 86400.0));
  app.add_option("--keepalive-timeout-seconds", connections.keepaliveTimeoutSeconds,
                 "How long a ping may go unanswered")
      ->capture_default_str()->check(CLI::Range(1.0, 3600.0));
  app.add_option("--lease-seconds", config.leaseSeconds, "Tile lease length")->capture_default_str()->check(CLI::Range(1.0, 3600.0));
  app.add_option("--max-tile-seconds", config.maxTileSeconds,
                 "Longest a tile may be baked (renewals stop after it; a hung bake's tile goes to another worker)")
      ->capture_default_str()->check(CLI::Range(1.0, 7 * 86400.0));
  app.add_option("--max-attempts", config.maxAttempts, "Failures or expiries of one tile that fail its job")
      ->capture_default_str()->check(CLI::Range(1, 100));
  app.add_option("--max-resolution", maxResolution, "Largest resolution accepted")->capture_default_str();
  app.add_option("--max-jobs", config.maxActiveJobs, "Most unfinished jobs held at once")->capture_default_str();
  app.add_option("--max-jobs-per-client", config.maxActiveJobsPerClient,
                 "Most unfinished jobs of one client (one owner in --tokens; admin tokens are not counted), so that "
                 "one client cannot take every place")
      ->capture_default_str()->check(CLI::Range(size_t(1), size_t(1000000)));
  app.add_option("--max-tiles-per-job", config.maxTilesPerJob, "Most tiles one job may have (65536: 256K in 1024-texel tiles)")
      ->capture_default_str()->check(CLI::Range(uint64_t(1), uint64_t(1) << 24));
  app.add_option("--max-upload-mb", maxUploadMb, "Largest scene upload in MiB")->capture_default_str();
  app.add_option("--import-memory-mb", importMemoryMb,
                 "Address space of the child process that imports an upload (assimp runs there, not in the server)")
      ->capture_default_str()->check(CLI::Range(64.0, 1048576.0));
  app.add_option("--import-seconds", config.import.seconds, "Longest one upload's import may take")
      ->capture_default_str()->check(CLI::Range(1.0, 86400.0));
  app.add_option("--max-concurrent-imports", config.maxConcurrentImports, "Uploads imported at once")
      ->capture_default_str()->check(CLI::Range(1, 64));
  app.add_option("--max-watches", config.maxWatches, "Job watches and track subscriptions open at once")
      ->capture_default_str()->check(CLI::Range(1, 100000));
  app.add_option("--max-pending-uploads", config.maxPendingUploads,
                 "Uploads started and not complete (idle ones are dropped to make room)")
      ->capture_default_str()->check(CLI::Range(size_t(1), size_t(1000000)));
  double clientUploadsMb = double(config.clientUploads.uploadingBytes >> 20);
  double clientScenesMb = double(config.clientUploads.storedBytes >> 20);
  app.add_option("--client-uploads-mb", clientUploadsMb,
                 "Bytes one client's uploads in progress may announce, in MiB (one owner in --tokens; admin tokens "
                 "are not counted)")
      ->capture_default_str()->check(CLI::Range(0.0, 1e9));
  app.add_option("--client-scenes-mb", clientScenesMb,
                 "Bytes of stored scenes one client may hold, in MiB (a scene counts for the client that uploaded "
                 "it first, until retention forgets it)")
      ->capture_default_str()->check(CLI::Range(0.0, 1e9));
  app.add_option("--quarantine-seconds", config.quarantineSeconds,
                 "A worker that fails 3 tiles in a row (or reports trouble of its own) gets no tile for this long, "
                 "doubling each time up to 10 minutes")
      ->capture_default_str()->check(CLI::Range(0.0, 86400.0));
  double keepFinishedHours = config.retention.keepFinishedSeconds / 3600;
  double uploadExpiryHours = config.retention.uploadExpirySeconds / 3600;
  app.add_option("--keep-finished-hours", keepFinishedHours,
                 "How long a finished job, its artifact and its place in listings are kept, and a stored scene no "
                 "job names after its last use (0: forever); a track's kept versions stay while the track holds them")
      ->capture_default_str()->check(CLI::Range(0.0, 1e6));
  app.add_option("--upload-expiry-hours", uploadExpiryHours,
                 "An upload that received no byte for this long is dropped (0: never)")
      ->capture_default_str()->check(CLI::Range(0.0, 1e6));
  app.add_option("--housekeeping-seconds", config.retention.intervalSeconds,
                 "How often finished jobs and idle uploads are checked against the two limits above")
      ->capture_default_str()->check(CLI::Range(0.1, 86400.0));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  spdlog::set_pattern("[%Y-%m-%d %H:%M:%S.%e] [%l] %v");
  if (check) {
    try {
      return checkCoordinator(listen, data, tlsCert, checkCa, minFreeMb);
    } catch (const std::exception& e) {
      std::printf("FAIL:    %s\n", e.what());
      return 1;
    }
  }
  try {
    // The file says that this run serves: one left by an earlier run must not say so
    // while this one starts (or fails to).
    if (!addressFile.empty()) {
      std::error_code ec;
      std::filesystem::remove(addressFile, ec);
      if (ec) throw cpvs::InputError("--address-file " + addressFile + ": cannot remove the old one: " + ec.message());
    }
    if (tlsCert.empty() != tlsKey.empty()) throw cpvs::InputError("give both --tls-cert and --tls-key, or neither");
    config.dataDir = data;
    config.retention.keepFinishedSeconds = keepFinishedHours * 3600;
    config.retention.uploadExpirySeconds = uploadExpiryHours * 3600;
    config.maxLog2Resolution = cpvs::parseResolution(maxResolution);
    config.maxUploadBytes = uint64_t(maxUploadMb * 1024 * 1024);
    config.clientUploads = {uint64_t(clientUploadsMb * 1024 * 1024), uint64_t(clientScenesMb * 1024 * 1024)};
    config.import.memoryBytes = uint64_t(importMemoryMb * 1024 * 1024);
    config.import.helper = cpvs::requiredImportProgram("cpvs-server");
    cpvs::server::TokenTable tokens = tokensFile.empty() ? cpvs::server::TokenTable() : cpvs::server::TokenTable::load(tokensFile);
    // Safe defaults: an open farm or tokens in cleartext only where nothing but this
    // machine can reach the port, unless the operator says so in as many words.
    const bool local = cpvs::net::isLoopbackAddress(listen);
    if (!local && !tokens.enabled() && !insecureOpen)
      throw cpvs::InputError("refusing to serve " + listen +
                             " without --tokens: anyone who reaches it could submit, cancel and download (make tokens "
                             "with deploy/make-secrets.sh, or give --insecure-open on a network you trust)");
    if (!local && tokens.enabled() && tlsCert.empty() && !allowPlaintextTokens)
      throw cpvs::InputError("refusing to take tokens in plaintext on " + listen +
                             ": give --tls-cert and --tls-key (deploy/make-secrets.sh --tls HOST), or "
                             "--allow-plaintext-tokens on a private network you trust");
    if (!tokens.enabled()) spdlog::warn("no --tokens: every caller may do everything");
    if (!metricsListen.empty() && !cpvs::net::isLoopbackAddress(metricsListen)) {
      if (!tokens.enabled() && !insecureOpen)
        throw cpvs::InputError("refusing to serve metrics on " + metricsListen +
                               " without --tokens (a metrics token for Prometheus), or give --insecure-open");
      if (tokens.enabled() && tlsCert.empty() && !allowPlaintextTokens)
        throw cpvs::InputError("refusing to take tokens in plaintext on the metrics address " + metricsListen +
                               ": give --tls-cert and --tls-key, or --allow-plaintext-tokens");
    }

    if (!workerCa.empty() && tlsCert.empty()) throw cpvs::InputError("--worker-ca needs --tls-cert and --tls-key");
    if (!workerCa.empty() && !tokens.enabled())
      throw cpvs::InputError("--worker-ca needs --tokens: clients and administrators still use tokens");
    std::shared_ptr<grpc::ServerCredentials> creds;
    if (tlsCert.empty()) {
      creds = grpc::InsecureServerCredentials();
    } else {
      // Checked now, so that a wrong file is a clear error at start; read again every
      // --tls-reload-seconds, so that a rotated certificate is served without a restart.
      for (const auto& [file, what] : {std::pair{tlsKey, "TLS key"}, {tlsCert, "TLS certificate"}, {workerCa, "worker CA"}})
        if (!file.empty() && readText(file, what).find("-----BEGIN") == std::string::npos)
          throw cpvs::InputError(std::string("the ") + what + " " + file + " is not PEM");
      auto files = std::make_shared<grpc::experimental::FileWatcherCertificateProvider>(tlsKey, tlsCert, workerCa,
                                                                                        unsigned(tlsReloadSeconds));
      grpc::experimental::TlsServerCredentialsOptions tls(files);
      tls.watch_identity_key_cert_pairs();
      if (!workerCa.empty()) {
        tls.watch_root_certs();
        tls.set_cert_request_type(GRPC_SSL_REQUEST_CLIENT_CERTIFICATE_AND_VERIFY);
      }
      creds = grpc::experimental::TlsServerCredentials(tls);
    }

    cpvs::server::Coordinator coordinator(config);
    cpvs::server::FarmServer server(coordinator, tokens, listen, creds, authLimits, !workerCa.empty(),
                                       connections);
    const std::string bound = server.address();
    if (!addressFile.empty()) {
      std::string text = bound + "\n";
      cpvs::writeFileAtomic(addressFile, std::vector<uint8_t>(text.begin(), text.end()));
    }
    spdlog::info("serving on {} ({}), data in {}", bound, tlsCert.empty() ? "plaintext" : "TLS", data);
    std::unique_ptr<cpvs::metrics::Endpoint> metrics;
    if (!metricsListen.empty()) {
      cpvs::metrics::EndpointOptions options{metricsListen, tlsCert, tlsKey, {}};
      if (tokens.enabled()) options.authorize = [&tokens](const std::string& token) { return tokens.readsMetrics(token); };
      metrics = std::make_unique<cpvs::metrics::Endpoint>(options, coordinator.metrics().registry(),
                                                          [&coordinator] { coordinator.refreshMetrics(); });
      if (!metricsAddressFile.empty()) {
        std::string text = metrics->address() + "\n";
        cpvs::writeFileAtomic(metricsAddressFile, std::vector<uint8_t>(text.begin(), text.end()));
      }
      spdlog::info("metrics on {}://{}/metrics", tlsCert.empty() ? "http" : "https", metrics->address());
    }
    std::signal(SIGTERM, onSignal);
    std::signal(SIGINT, onSignal);
    while (!gStop) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    spdlog::info("stopping");
    metrics.reset();
    server.shutdown(5);
    coordinator.stop();
    return 0;
  } catch (const cpvs::InputError& e) {
    spdlog::error("{}", e.what());
    return 2;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 3;
  }
}
