// What the farm's operators see, as separate processes on loopback: the coordinator's and
// a worker's Prometheus endpoints (tokens, TLS), the counts they report against the job
// that ran (tiles queued before a worker comes, leases granted and completed, artifact
// bytes), and a worker's drain: SIGTERM with a short --drain-seconds gives its tile back
// as interrupted, at no cost to the tile's attempts.
#include <gtest/gtest.h>

#include <csignal>
#include <filesystem>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <regex>
#include <string>
#include <thread>

#include "cpvs/base/file.h"
#include "cpvs/scene/obj_writer.h"
#include "cpvs/scene/source.h"
#include "process_testing.h"

namespace cpvs {
namespace {

namespace fs = std::filesystem;
using testing::ChildProcess;
using Ran = testing::CommandResult;

const std::string kClientToken = "9c1f6a0e5d8b47a2b3c4d5e6f708192a3b4c5d6e";
const std::string kWorkerToken = "0a7e3c9b5f1d48e6a2c4b6d8f0e1a3c5b7d9f1e3";
const std::string kMetricsToken = "5b2d8f4a6c0e49b1d3f5a7c9e1b3d5f7a9c1e3b5";

Ran runCli(const std::string& args) { return testing::runShell("timeout 300 '" CPVS_CLI "' " + args + " 2>&1"); }

/// One scrape: the HTTP status and the body.
struct Scrape {
  int status = 0;
  std::string body;

  /// The value of the sample `series` (a name with its labels as written), NaN when absent.
  double operator[](const std::string& series) const {
    const std::regex line("(^|\n)" + std::regex_replace(series, std::regex(R"([{}.+"])"), R"(\$&)") + " ([^\n]+)");
    std::smatch m;
    if (!std::regex_search(body, m, line)) return std::nan("");
    return std::stod(m[2]);
  }
};

/// Every sample of a scrape by series, and every family's type, as Prometheus parses the
/// text format: "# TYPE name type" lines, then "name{labels} value" lines.
struct Parsed {
  std::map<std::string, double> samples;
  std::map<std::string, std::string> types;
};

Parsed parse(const std::string& body) {
  Parsed p;
  std::istringstream in(body);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("# TYPE ", 0) == 0) {
      std::istringstream words(line.substr(7));
      std::string name, type;
      words >> name >> type;
      p.types[name] = type;
    } else if (!line.empty() && line[0] != '#') {
      const size_t space = line.rfind(' ');
      p.samples[line.substr(0, space)] = std::stod(line.substr(space + 1));
    }
  }
  return p;
}

/// The family a series belongs to (a histogram's _bucket, _sum and _count are its own).
std::string familyOf(const std::string& series, const Parsed& p) {
  std::string name = series.substr(0, series.find('{'));
  if (p.types.count(name)) return name;
  for (const char* suffix : {"_bucket", "_sum", "_count"})
    if (name.size() > std::strlen(suffix) && name.compare(name.size() - std::strlen(suffix), std::string::npos, suffix) == 0)
      return name.substr(0, name.size() - std::strlen(suffix));
  return name;
}

Scrape scrape(const std::string& url, const std::string& token, const std::string& extra = "") {
  const std::string auth = token.empty() ? "" : " -H 'Authorization: Bearer " + token + "'";
  Ran r = testing::runShell("curl -s --max-time 10" + auth + " " + extra + " -w '\\n%{http_code}' '" + url + "'");
  Scrape s;
  const size_t last = r.out.rfind('\n');
  if (last == std::string::npos) return s;
  s.status = std::atoi(r.out.c_str() + last + 1);
  s.body = r.out.substr(0, last);
  return s;
}

class MetricsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("cpvs_metrics_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    std::ofstream(path("tokens")) << "client " << kClientToken << "\nworker " << kWorkerToken << "\nmetrics "
                                  << kMetricsToken << "\n";
    std::ofstream(path("metrics.token")) << kMetricsToken << "\n";
    writeObj(path("city.obj"), openScene("city:3:5"));
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static std::string path(const std::string& name) { return (dir_ / name).string(); }

  /// A coordinator serving metrics; returns its RPC address (its metrics address in `metrics`).
  std::string startServer(const std::string& name, std::string& metrics, const std::vector<std::string>& extra = {}) {
    for (const char* f : {".address", ".metrics"}) fs::remove(path(name + f));
    std::vector<std::string> argv{CPVS_SERVER, "--listen", "127.0.0.1:0", "--data", path(name + ".data"),
                                  "--address-file", path(name + ".address"), "--tokens", path("tokens"),
                                  "--metrics", "127.0.0.1:0", "--metrics-address-file", path(name + ".metrics")};
    argv.insert(argv.end(), extra.begin(), extra.end());
    processes_.push_back(std::make_unique<ChildProcess>(argv, path(name + ".log")));
    const std::string address = testing::waitForFile(path(name + ".address"), 30);
    metrics = testing::waitForFile(path(name + ".metrics"), 30);
    EXPECT_FALSE(metrics.empty()) << processes_.back()->log();
    return address;
  }

  ChildProcess& startWorker(const std::string& address, const std::string& name, const std::vector<std::string>& flags) {
    std::vector<std::string> argv{CPVS_WORKER, "--server", address, "--token", kWorkerToken, "--cache",
                                  path(name + ".cache"), "--id", name};
    argv.insert(argv.end(), flags.begin(), flags.end());
    processes_.push_back(std::make_unique<ChildProcess>(argv, path(name + ".log")));
    return *processes_.back();
  }

  Ran submit(const std::string& address, const std::string& requestId, const std::string& spec, bool wait) {
    return runCli("submit --server " + address + " --token " + kClientToken + " " + path("city.obj") + " " + spec +
                  " --request-id " + requestId + (wait ? " --wait --json --out " + path(requestId + ".cpvs") : ""));
  }

  void TearDown() override {
    for (auto& p : processes_) p->stop(SIGKILL);
  }

  static fs::path dir_;
  std::vector<std::unique_ptr<ChildProcess>> processes_;
};
fs::path MetricsTest::dir_;

constexpr const char* kSpec = "--sun-dir 0.3,-1,0.2 --resolution 1024 --tile-size 128";  // 64 tiles

TEST_F(MetricsTest, TheCoordinatorAndAWorkerCountTheJobThatRan) {
  std::string metrics;
  const std::string address = startServer("s", metrics);
  const std::string url = "http://" + metrics + "/metrics";

  // Only a metrics (or admin) token reads them.
  EXPECT_EQ(scrape(url, "").status, 401);
  EXPECT_EQ(scrape(url, kClientToken).status, 401);
  EXPECT_EQ(scrape(url, kWorkerToken).status, 401);
  EXPECT_EQ(scrape(url, kMetricsToken + "0").status, 401);
  Scrape idle = scrape(url, kMetricsToken);
  ASSERT_EQ(idle.status, 200) << idle.body;
  EXPECT_EQ(idle["cpvs_store_healthy"], 1);
  EXPECT_EQ(idle["cpvs_jobs{state=\"queued\"}"], 0);
  EXPECT_GT(idle["process_resident_memory_bytes"], 1e6);
  EXPECT_GT(idle["process_open_fds"], 3);
  EXPECT_GT(idle["cpvs_store_bytes"], 0);

  // A job and no worker: its tiles wait, and the autoscaler's gauge says so (those with
  // nothing in them are never leased: checked once the job says how many).
  Ran submitted = submit(address, "counted", kSpec, false);
  ASSERT_EQ(submitted.status, 0) << submitted.out;
  Scrape waiting = scrape(url, kMetricsToken);
  EXPECT_EQ(waiting["cpvs_jobs{state=\"queued\"}"], 1) << waiting.body;
  EXPECT_EQ(waiting["cpvs_tiles_outstanding{state=\"leased\"}"], 0);
  EXPECT_EQ(waiting["cpvs_leases_total{event=\"granted\"}"], 0);

  startWorker(address, "w", {"--metrics", "127.0.0.1:0", "--metrics-address-file", path("w.metrics"),
                             "--metrics-token-file", path("metrics.token")});
  Ran done = submit(address, "counted", kSpec, true);  // the same request: waits for it
  ASSERT_EQ(done.status, 0) << done.out;
  const auto fileBytes = double(fs::file_size(path("counted.cpvs")));
  std::smatch untouched;
  ASSERT_TRUE(std::regex_search(done.out, untouched, std::regex(R"("tiles_untouched": (\d+))"))) << done.out;
  const double baked = 64 - std::stod(untouched[1]);
  EXPECT_GT(baked, 32);
  EXPECT_EQ(waiting["cpvs_tiles_outstanding{state=\"queued\"}"], baked);

  Scrape after = scrape(url, kMetricsToken);
  // The text format as Prometheus reads it: every family typed, every series of a family
  // named by it, and counters (and histograms) that only grew since the scrape before.
  const Parsed before = parse(waiting.body), now = parse(after.body);
  EXPECT_EQ(now.types.at("cpvs_leases_total"), "counter");
  EXPECT_EQ(now.types.at("cpvs_jobs"), "gauge");
  EXPECT_EQ(now.types.at("cpvs_tiles_outstanding"), "gauge");
  EXPECT_EQ(now.types.at("cpvs_tile_stage_seconds"), "histogram");
  EXPECT_EQ(now.types.at("cpvs_merge_tile_seconds"), "histogram");
  EXPECT_EQ(now.types.at("process_cpu_seconds_total"), "counter");
  EXPECT_GT(now.samples.size(), 50u);
  for (const auto& [series, value] : now.samples) {
    const std::string family = familyOf(series, now);
    ASSERT_TRUE(now.types.count(family)) << series << " has no TYPE";
    EXPECT_TRUE(std::regex_match(series, std::regex(R"([a-z_]+(\{[a-z_]+="[^"]*"(,[a-z_]+="[^"]*")*\})?)"))) << series;
    if (now.types.at(family) == "gauge") continue;
    const auto earlier = before.samples.find(series);
    if (earlier != before.samples.end()) {
      EXPECT_GE(value, earlier->second) << series << " went down";
    }
  }
  EXPECT_EQ(after["cpvs_jobs{state=\"done\"}"], 1) << after.body;
  EXPECT_EQ(after["cpvs_jobs{state=\"queued\"}"], 0);
  EXPECT_EQ(after["cpvs_tiles_outstanding{state=\"queued\"}"], 0);
  EXPECT_EQ(after["cpvs_leases_total{event=\"granted\"}"], baked);
  EXPECT_EQ(after["cpvs_leases_total{event=\"completed\"}"], baked);
  EXPECT_EQ(after["cpvs_leases_total{event=\"failed_tile\"}"], 0);
  EXPECT_EQ(after["cpvs_tile_result_bytes_count"], baked);
  EXPECT_EQ(after["cpvs_merge_tile_seconds_count"], 64);
  EXPECT_EQ(after["cpvs_artifact_write_seconds_count"], 1);
  EXPECT_EQ(after["cpvs_artifact_written_bytes_total"], fileBytes);
  EXPECT_EQ(after["cpvs_artifacts_stored_bytes"], fileBytes);
  EXPECT_EQ(after["cpvs_merge_backlog"], 0);
  EXPECT_EQ(after["cpvs_streams_open{kind=\"watch\"}"], 0) << "the client's watch ended with the job";
  EXPECT_EQ(after["cpvs_tile_stage_seconds_count{stage=\"encode\"}"], baked) << after.body;

  // The worker's own endpoint, behind the metrics token it was given.
  const std::string workerUrl = "http://" + testing::waitForFile(path("w.metrics"), 10) + "/metrics";
  EXPECT_EQ(scrape(workerUrl, "").status, 401);
  Scrape worker = scrape(workerUrl, kMetricsToken);
  ASSERT_EQ(worker.status, 200);
  EXPECT_EQ(worker["cpvs_worker_tiles_total{outcome=\"returned\"}"], baked) << worker.body;
  EXPECT_EQ(worker["cpvs_worker_tiles_total{outcome=\"failed\"}"], 0);
  EXPECT_EQ(worker["cpvs_worker_slots"], 1);
  EXPECT_EQ(worker["cpvs_worker_slots_busy"], 0);
  EXPECT_EQ(worker["cpvs_worker_draining"], 0);
  EXPECT_EQ(worker["cpvs_worker_tile_stage_seconds_count{stage=\"encode\"}"], baked);
}

TEST_F(MetricsTest, MetricsOverTlsAndRefusedWhereTheyWouldLeak) {
  Ran made = testing::runShell("bash '" CPVS_SOURCE_DIR "/deploy/make-secrets.sh' --dir '" + path("tls") +
                               "' --tls localhost 2>&1");
  ASSERT_EQ(made.status, 0) << made.out;
  std::string metrics;
  startServer("tls", metrics, {"--tls-cert", path("tls/tls.crt"), "--tls-key", path("tls/tls.key")});
  const std::string port = metrics.substr(metrics.rfind(':') + 1);
  // The certificate names localhost: the scrape goes there, trusting the farm's CA.
  const std::string url = "https://localhost:" + port + "/metrics";
  Scrape trusted = scrape(url, kMetricsToken, "--cacert '" + path("tls/ca.crt") + "'");
  EXPECT_EQ(trusted.status, 200) << trusted.body;
  EXPECT_EQ(trusted["cpvs_store_healthy"], 1);
  EXPECT_EQ(scrape(url, "", "--cacert '" + path("tls/ca.crt") + "'").status, 401);
  EXPECT_EQ(scrape(url, kMetricsToken).status, 0) << "a certificate from an unknown CA is not trusted";
  EXPECT_EQ(scrape("http://localhost:" + port + "/metrics", kMetricsToken).status != 200, true);

  // The readiness check speaks the coordinator's TLS, trusting the farm's CA.
  Ran check = testing::runShell("timeout 60 '" CPVS_SERVER "' --check --listen " + testing::waitForFile(path("tls.address"), 5) +
                                " --data '" + path("tls.data") + "' --tls-cert '" + path("tls/tls.crt") + "' --ca '" +
                                path("tls/ca.crt") + "' 2>&1");
  EXPECT_EQ(check.status, 0) << check.out;
  EXPECT_NE(check.out.find("(TLS) answers"), std::string::npos) << check.out;
  EXPECT_NE(check.out.find("the TLS certificate"), std::string::npos) << check.out;

  // A renewed certificate (another CA's here) is served from the next scrape, no restart.
  Ran other = testing::runShell("bash '" CPVS_SOURCE_DIR "/deploy/make-secrets.sh' --dir '" + path("tls-next") +
                                "' --tls localhost 2>&1");
  ASSERT_EQ(other.status, 0) << other.out;
  for (const char* f : {"tls.crt", "tls.key"}) {
    std::filesystem::copy_file(path(std::string("tls-next/") + f), path(std::string("tls/") + f + ".new"),
                               std::filesystem::copy_options::overwrite_existing);
    std::filesystem::rename(path(std::string("tls/") + f + ".new"), path(std::string("tls/") + f));
  }
  EXPECT_EQ(scrape(url, kMetricsToken, "--cacert '" + path("tls-next/ca.crt") + "'").status, 200);
  EXPECT_EQ(scrape(url, kMetricsToken, "--cacert '" + path("tls/ca.crt") + "'").status, 0) << "the old CA no longer";

  // Tokens in plaintext beyond loopback, or an open endpoint there, are refused in words.
  Ran plain = testing::runShell("timeout 30 '" CPVS_SERVER "' --data '" + path("plain.data") + "' --tokens '" +
                                path("tokens") + "' --metrics 0.0.0.0:0 2>&1");
  EXPECT_EQ(plain.status, 2) << plain.out;
  EXPECT_NE(plain.out.find("plaintext on the metrics address"), std::string::npos) << plain.out;
  Ran open = testing::runShell("timeout 30 '" CPVS_WORKER "' --server 127.0.0.1:1 --cache '" + path("open.cache") +
                               "' --metrics 0.0.0.0:0 2>&1");
  EXPECT_EQ(open.status, 2) << open.out;
  EXPECT_NE(open.out.find("without --metrics-token-file"), std::string::npos) << open.out;
  Ran bad = testing::runShell("timeout 30 '" CPVS_SERVER "' --data '" + path("bad.data") +
                              "' --metrics 127.0.0.1:99999 2>&1");
  EXPECT_EQ(bad.status, 2) << bad.out;
  EXPECT_NE(bad.out.find("no port number"), std::string::npos) << bad.out;
}

// Readiness that means something: `cpvs-server --check` and `cpvs-worker --check` pass on a
// working farm and fail, naming why, on a coordinator that does not answer (stopped with
// SIGSTOP), a folder without the room asked for, a worker the coordinator has not
// answered, a certificate that is not one.
TEST_F(MetricsTest, ChecksPassOnAWorkingFarmAndSayWhyNot) {
  std::string metrics;
  const std::string address = startServer("checked", metrics);
  const std::string server = "timeout 60 '" CPVS_SERVER "' --check --listen " + address + " --data '" +
                             path("checked.data") + "'";
  Ran ready = testing::runShell(server + " 2>&1");
  EXPECT_EQ(ready.status, 0) << ready.out;
  EXPECT_NE(ready.out.find("its job store takes writes"), std::string::npos) << ready.out;
  EXPECT_NE(ready.out.find("leases move"), std::string::npos) << ready.out;
  Ran full = testing::runShell(server + " --min-free-mb 1000000000 2>&1");
  EXPECT_EQ(full.status, 1) << full.out;
  EXPECT_NE(full.out.find("FAIL:    " + path("checked.data") + " has"), std::string::npos) << full.out;
  Ran notPem = testing::runShell(server + " --tls-cert '" + path("tokens") + "' 2>&1");
  EXPECT_EQ(notPem.status, 1) << notPem.out;
  EXPECT_NE(notPem.out.find("cannot be read as PEM"), std::string::npos) << notPem.out;

  const std::string worker = "timeout 60 '" CPVS_WORKER "' --check --cache '" + path("checked-w.cache") + "'";
  std::filesystem::create_directories(path("checked-w.cache"));
  Ran unborn = testing::runShell(worker + " 2>&1");
  EXPECT_EQ(unborn.status, 1) << unborn.out;
  EXPECT_NE(unborn.out.find("has not answered this worker yet"), std::string::npos) << unborn.out;
  ChildProcess& w = startWorker(address, "checked-w", {});
  ASSERT_TRUE(w.waitForLog("pulling tiles", 30)) << w.log();
  Ran alive;
  for (int i = 0; i < 100 && (alive = testing::runShell(worker + " 2>&1")).status != 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(alive.status, 0) << alive.out;
  EXPECT_NE(alive.out.find("takes a file"), std::string::npos) << alive.out;

  // A coordinator that does not answer: not ready; and after its silence, the worker not alive.
  ::kill(processes_[0]->pid(), SIGSTOP);
  Ran stopped = testing::runShell(server + " 2>&1");
  EXPECT_EQ(stopped.status, 1) << stopped.out;
  EXPECT_NE(stopped.out.find("is not ready"), std::string::npos) << stopped.out;
  std::this_thread::sleep_for(std::chrono::seconds(2));
  Ran silent = testing::runShell(worker + " --max-silence 1 2>&1");
  EXPECT_EQ(silent.status, 1) << silent.out;
  EXPECT_NE(silent.out.find("FAIL:    the coordinator answered this worker"), std::string::npos) << silent.out;
  ::kill(processes_[0]->pid(), SIGCONT);
  Ran back = testing::runShell(server + " 2>&1");
  EXPECT_EQ(back.status, 0) << back.out;
}

// A drain that cannot wait: SIGTERM with a short --drain-seconds gives the tile in
// progress back (interrupted, no attempt counted) and the process leaves at once; the tile
// goes to the next worker and the job completes.
TEST_F(MetricsTest, ADrainPastItsTimeGivesTheTileBackAndLeaves) {
  std::string metrics;
  const std::string address = startServer("drain", metrics);
  const std::string url = "http://" + metrics + "/metrics";
  // One ray per texel on one thread: each 4K tile takes a second or more.
  const std::string spec = "--sun-dir 0.3,-1,0.2 --resolution 8192 --tile-size 4096 --renderer embree";
  ASSERT_EQ(submit(address, "drained", spec, false).status, 0);
  ChildProcess& leaving = startWorker(address, "leaving", {"--threads", "1", "--drain-seconds", "0.2"});
  ASSERT_TRUE(leaving.waitForLog("baking", 60)) << leaving.log();
  const auto signalled = std::chrono::steady_clock::now();
  EXPECT_EQ(leaving.stop(SIGTERM), 0) << leaving.log();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - signalled).count(), 5);
  EXPECT_NE(leaving.log().find("drain time up: gave 1 tile(s) in progress back"), std::string::npos) << leaving.log();
  Scrape given = scrape(url, kMetricsToken);
  EXPECT_EQ(given["cpvs_leases_total{event=\"interrupted\"}"], 1) << given.body;
  EXPECT_EQ(given["cpvs_leases_total{event=\"failed_tile\"}"], 0);

  startWorker(address, "staying", {});
  Ran done = submit(address, "drained", spec, true);
  ASSERT_EQ(done.status, 0) << done.out;
  Ran local = runCli("bake " + path("city.obj") + " " + spec + " -q -o " + path("drained-local.cpvs"));
  ASSERT_EQ(local.status, 0) << local.out;
  EXPECT_EQ(readFile(path("drained.cpvs")), readFile(path("drained-local.cpvs")));
}

}  // namespace
}  // namespace cpvs
