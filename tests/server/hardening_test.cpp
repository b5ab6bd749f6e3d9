// Findings of the reliability review (../shared/notes/reliability-review.md), each
// reproduced by the test named after it before it was fixed.
#include <gtest/gtest.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>
#include <sqlite3.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>
#include <tuple>

#include "cpvs/base/error.h"
#include "cpvs/base/file.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/text.h"
#include "cpvs/net/channel.h"
#include "cpvs/net/convert.h"
#include "cpvs/net/health.h"
#include "rpc/gatekeeper.h"
#include "cpvs/net/status.h"
#include "cpvs/scene/mesh_file.h"
#include "error_testing.h"
#include "cpvs/scene/obj_writer.h"
#include "cpvs/scene/source.h"
#include "farm_testing.h"
#include "store/farm_store.h"

namespace cpvs {
namespace {

namespace fs = std::filesystem;
namespace pb = ::cpvs::v1;
using testing::ForwardingWorkers;
using testing::InProcessFarm;
using testing::ServiceServer;
using testing::TempDir;

server::JobRecord oneTileJob(const std::string& id) {
  server::JobRecord j;
  j.id = id;
  j.requestId = "req-" + id;
  j.sceneHash = std::string(32, 'b');
  j.geometryHash = std::string(32, 'c');
  j.createdMs = 1000;
  j.tilesTotal = 1;
  OrthoGrid g;
  g.frame = LightFrame::fromDirection({0, -1, 0});
  g.log2Resolution = 6;
  j.grids = {server::JobGrid{gridSpecOf(g)}};
  return j;
}

/// Leases one tile through the Workers service, as a worker would.
pb::TileLease leaseThroughRpc(const net::Connection& c) {
  auto workers = pb::Workers::NewStub(net::makeChannel(c));
  pb::LeaseRequest lr;
  lr.set_worker_id("w");
  pb::TileLease lease;
  grpc::ClientContext ctx;
  EXPECT_TRUE(workers->LeaseTile(&ctx, lr, &lease).ok());
  return lease;
}

/// Log lines written while `body` runs.
template <class Body>
std::string logOf(Body&& body) {
  std::ostringstream log;
  auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(log);
  spdlog::default_logger()->sinks().push_back(sink);
  body();
  spdlog::default_logger()->sinks().pop_back();
  return log.str();
}

// R13: a cancel that lands while the merge writes the artifact must stand; finishing the
// job afterwards must not turn CANCELLED into DONE.
TEST(Hardening, R13_ACancelledJobStaysCancelledWhenItsMergeFinishes) {
  TempDir dir("cpvs_r13");
  server::FarmStore store(dir / "farm.sqlite");
  store.createJob(oneTileJob("j1"));
  store.setJobState("j1", server::JobState::Cancelled, "cancelled", 2000);
  EXPECT_FALSE(store.finishJob("j1", 10, 20, 30, std::string(32, 'd'), 3000));
  EXPECT_EQ(store.job("j1")->state, server::JobState::Cancelled);
  store.createJob(oneTileJob("j2"));
  EXPECT_TRUE(store.finishJob("j2", 10, 20, 30, std::string(32, 'd'), 3000));
  EXPECT_EQ(store.job("j2")->state, server::JobState::Done);
}

// R20: a failure reported under a lease that is no longer the tile's current one must
// not return the tile, now leased to another worker, to the queue.
TEST(Hardening, R20_AStaleLeaseCannotRequeueAnotherWorkersLease) {
  TempDir dir("cpvs_r20");
  server::FarmStore store(dir / "farm.sqlite");
  store.createJob(oneTileJob("j"));
  ASSERT_TRUE(store.leaseNextTile("w1", "l1", 1000, 2000).has_value());
  ASSERT_EQ(store.expireLeases(3000).size(), 1u);
  ASSERT_TRUE(store.leaseNextTile("w2", "l2", 3000, 9000).has_value());
  store.requeueTile("l1", "late failure of the first worker");
  EXPECT_EQ(store.tileState("j", 0), server::TileState::Leased);
  EXPECT_TRUE(store.renewLease("l2", 9500));  // still w2's
  EXPECT_GT(store.requeueTile("l2", "w2 failed"), 0);
  EXPECT_EQ(store.tileState("j", 0), server::TileState::Queued);
}

// R8: a failure reason cut at the byte limit inside a multi-byte character made every
// later ListJobs fail to parse (proto3 strings must be UTF-8).
TEST(Hardening, R8_FailureReasonsStayValidUtf8) {
  EXPECT_EQ(validUtf8Prefix("abc", 10), "abc");
  EXPECT_EQ(validUtf8Prefix("ab\xC3\xA9", 3), "ab");                 // é not split
  EXPECT_EQ(validUtf8Prefix("a\xFF" "b", 10), "a\xEF\xBF\xBD" "b");  // invalid byte replaced
  EXPECT_EQ(validUtf8Prefix("\xE2\x82", 10), "\xEF\xBF\xBD");          // truncated sequence replaced
  EXPECT_EQ(validUtf8Prefix("\xF0\x9F\x98\x80!", 5), "\xF0\x9F\x98\x80!");

  TempDir dir("cpvs_r8");
  InProcessFarm farm(dir / "data");
  farm.client.submit("r8", farm.uploadAndSpec(dir / "box.obj", "city:1:1", "64"));
  auto workers = pb::Workers::NewStub(net::makeChannel(farm.connection()));
  for (int attempt = 0; attempt < 3; ++attempt) {
    const pb::TileLease lease = leaseThroughRpc(farm.connection());
    ASSERT_TRUE(lease.granted());
    pb::FailRequest fr;
    fr.set_lease_id(lease.lease_id());
    fr.set_reason(std::string(999, 'x') + "\xC3\xA9 and more");  // é across byte 1000
    pb::FailReply reply;
    grpc::ClientContext fctx;
    ASSERT_TRUE(workers->FailTile(&fctx, fr, &reply).ok());
  }
  const std::vector<client::JobStatus> jobs = farm.client.list(true);  // parses: the error is UTF-8
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].state, client::JobState::Failed);
  EXPECT_NE(jobs[0].error.find("failed 3 times"), std::string::npos);
}

// R15 (and R1's server part): CompleteTile under a lease nobody holds is refused at the
// first chunk, not after the whole announced stream.
TEST(Hardening, R15_AResultUnderAnUnknownLeaseIsRefusedAtItsFirstChunk) {
  TempDir dir("cpvs_r15");
  InProcessFarm farm(dir / "data");
  auto workers = pb::Workers::NewStub(net::makeChannel(farm.connection()));
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
  pb::CompleteReply reply;
  auto writer = workers->CompleteTile(&ctx, &reply);
  pb::TileResultChunk chunk;
  chunk.set_lease_id("l0123456789abcdef");
  chunk.set_total_size(uint64_t(1) << 31);
  chunk.set_checksum(std::string(32, 'a'));
  chunk.set_data(std::string(1 << 20, 'z'));
  const auto start = std::chrono::steady_clock::now();
  writer->Write(chunk);  // and the stream stays open
  const grpc::Status s = writer->Finish();
  EXPECT_EQ(s.error_code(), grpc::StatusCode::NOT_FOUND) << s.error_message();
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(2));
}

// R3/R5: bytes past the acknowledged offset (a crash between the write and the commit)
// must not end up inside the scene: the resumed upload writes at that offset.
TEST(Hardening, R3_AnUploadResumesAtTheAcknowledgedOffsetNotTheFilesEnd) {
  TempDir dir("cpvs_r3");
  const std::string obj = dir / "box.obj";
  writeObj(obj, openScene("city:1:1"));
  const std::vector<uint8_t> bytes = readFile(obj);
  const std::string hash = contentHash(bytes.data(), bytes.size()).hex();
  {
    server::CoordinatorConfig config;
    config.dataDir = dir / "data";
    server::Coordinator coordinator(config);
    pb::UploadSceneChunk first;
    first.set_scene_hash(hash);
    first.set_file_name("box.obj");
    first.set_total_size(bytes.size());
    first.set_offset(0);
    coordinator.scenes().beginUpload(first);
    coordinator.scenes().appendUpload(hash, 0, std::string(bytes.begin(), bytes.begin() + 100));
  }
  // As if the coordinator died after writing more bytes but before acknowledging them.
  std::ofstream(dir / "data/scenes/" + hash + ".part", std::ios::app) << "garbage not acknowledged";
  InProcessFarm farm(dir / "data");
  EXPECT_EQ(farm.coordinator.scenes().uploadStatus(hash).received(), 100u);
  const client::FarmClient::UploadResult up = farm.client.uploadScene(obj);
  EXPECT_EQ(up.resumedFrom, 100u);
  EXPECT_TRUE(farm.coordinator.scenes().uploadStatus(hash).complete());
}

// R5: a coordinator that died after storing an upload's bytes but before marking the
// scene imported left it stuck: every retry read a `.part` that no longer existed. The
// stored file is now checked and imported again; with the bytes gone, the upload starts
// over.
TEST(Hardening, R5_AnUploadInterruptedInItsImportCompletesOnTheNextTry) {
  TempDir dir("cpvs_r5");
  const std::string obj = dir / "box.obj";
  writeObj(obj, openScene("city:1:1"));
  std::string hash;
  {
    InProcessFarm farm(dir / "data");
    hash = farm.client.uploadScene(obj).sceneHash;
  }
  auto markIncomplete = [&] {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open((dir / "data/farm.sqlite").c_str(), &db), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(db, "UPDATE scenes SET complete = 0", nullptr, nullptr, nullptr), SQLITE_OK);
    sqlite3_close(db);
  };
  markIncomplete();  // renamed into place, not yet marked imported
  {
    InProcessFarm farm(dir / "data");
    EXPECT_FALSE(farm.coordinator.scenes().uploadStatus(hash).complete());
    const client::FarmClient::UploadResult up = farm.client.uploadScene(obj);
    EXPECT_EQ(up.sceneHash, hash);
    EXPECT_GT(up.triangles, 0u);
    EXPECT_TRUE(farm.coordinator.scenes().uploadStatus(hash).complete());
    EXPECT_EQ(farm.client.submit("r5", farm.uploadAndSpec(obj, "city:1:1", "64")).state != client::JobState::Failed, true);
  }
  markIncomplete();
  for (const auto& entry : std::filesystem::directory_iterator(dir / "data/scenes"))
    if (entry.path().filename().string().starts_with(hash)) std::filesystem::remove(entry.path());  // and the bytes lost
  InProcessFarm farm(dir / "data");
  try {
    farm.client.uploadScene(obj);
    ADD_FAILURE() << "a lost upload was reported stored";
  } catch (const client::FarmCallError& e) {
    EXPECT_EQ(e.kind(), net::ErrorKind::DataLoss) << e.what();
    EXPECT_EQ(std::string(e.what()).find(dir / "data"), std::string::npos) << e.what();
  }
  const client::FarmClient::UploadResult again = farm.client.uploadScene(obj);
  EXPECT_EQ(again.resumedFrom, 0u);
  EXPECT_TRUE(farm.coordinator.scenes().uploadStatus(hash).complete());
}

// R2: tile_size 8 at 256K asked the store for 2^30 tile rows in one transaction.
TEST(Hardening, R2_AJobOfTooManyTilesIsRefusedAtOnce) {
  TempDir dir("cpvs_r2");
  InProcessFarm farm(dir / "data");
  net::BakeSpec spec = farm.uploadAndSpec(dir / "box.obj", "city:1:1", "256K");
  spec.options.tileSize = 8;
  const auto start = std::chrono::steady_clock::now();
  try {
    farm.client.submit("r2", spec);
    ADD_FAILURE() << "a job of 2^30 tiles was accepted";
  } catch (const client::FarmCallError& e) {
    EXPECT_EQ(e.kind(), net::ErrorKind::InvalidArgument);
    EXPECT_NE(std::string(e.what()).find("tiles of at least 1024 texels"), std::string::npos) << e.what();
  }
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(2));
  EXPECT_TRUE(farm.client.list(true).empty());
}

// R14: a second coordinator on the same data folder, or on the same port, is refused.
TEST(Hardening, R14_OneCoordinatorPerDataFolderAndPerPort) {
  TempDir dir("cpvs_r14");
  InProcessFarm first(dir / "data");
  server::CoordinatorConfig same;
  same.dataDir = dir / "data";
  try {
    server::Coordinator second(same);
    ADD_FAILURE() << "two coordinators opened one data folder";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("in use by another cpvs-server"), std::string::npos) << e.what();
  }
  server::CoordinatorConfig other;
  other.dataDir = dir / "other";
  server::Coordinator otherCoordinator(other);
  EXPECT_THROW(server::FarmServer(otherCoordinator, first.tokens, first.server.address()), InputError);
}

// R25: temporaries of atomic writes that a crash left behind are removed at start.
TEST(Hardening, R25_TemporariesLeftByACrashAreRemovedAtStart) {
  TempDir dir("cpvs_r25");
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  { server::Coordinator once(config); }
  const std::string stale = dir / "data/artifacts/j1.cpvs.tmp.4242.0";
  std::ofstream(stale) << "half an artifact";
  server::Coordinator again(config);
  EXPECT_FALSE(fs::exists(stale));
}

// R16: worker-supplied stage names became stored rows without bound; only the pipeline's
// stages are taken now.
TEST(Hardening, R16_AResultWithAStageThePipelineDoesNotHaveIsRefused) {
  TempDir dir("cpvs_r16");
  InProcessFarm farm(dir / "data");
  farm.client.submit("r16", farm.uploadAndSpec(dir / "box.obj", "city:1:1", "64"));
  const pb::TileLease lease = leaseThroughRpc(farm.connection());
  auto workers = pb::Workers::NewStub(net::makeChannel(farm.connection()));
  grpc::ClientContext ctx;
  pb::CompleteReply reply;
  auto writer = workers->CompleteTile(&ctx, &reply);
  pb::TileResultChunk chunk;
  chunk.set_lease_id(lease.lease_id());
  chunk.set_total_size(4);
  chunk.set_checksum(std::string(32, 'a'));
  auto* st = chunk.add_stages();
  st->set_stage("padding-0001");
  st->set_seconds(1);
  chunk.set_data("abcd");
  writer->Write(chunk);
  writer->WritesDone();
  const grpc::Status s = writer->Finish();
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("unknown stage 'padding-0001'"), std::string::npos) << s.error_message();
}

// R21: a download whose stored artifact is gone named the data folder to the client.
TEST(Hardening, R21_AMissingStoredFileDoesNotNameTheDataFolder) {
  TempDir dir("cpvs_r21");
  InProcessFarm farm(dir / "data");
  worker::TileWorker tileWorker(testing::workerConfig(farm.connection(), dir / "cache"));
  std::thread workerThread([&] { tileWorker.run(); });
  const net::BakeSpec spec = farm.uploadAndSpec(dir / "box.obj", "city:1:1", "64");
  const client::JobStatus job = farm.client.watch(farm.client.submit("r21", spec).jobId);
  tileWorker.stop();
  workerThread.join();
  ASSERT_EQ(job.state, client::JobState::Done);
  fs::remove(farm.coordinator.jobs().artifactPath(job.jobId, nullptr));
  try {
    farm.client.download(job.jobId, dir / "out.cpvs");
    ADD_FAILURE() << "downloaded a missing artifact";
  } catch (const client::FarmCallError& e) {
    EXPECT_EQ(e.kind(), net::ErrorKind::DataLoss) << e.what();
    EXPECT_EQ(std::string(e.what()).find(dir / "data"), std::string::npos) << e.what();
  }
  // Nor does a job failed by an error that names a file in it (a merge that could not read).
  const std::string failing = farm.client.submit("r21-failed", spec).jobId;
  farm.coordinator.jobs().failJob(failing, "merge failed: cannot read " + (dir / "data") + "/tiles/x/0.cpvt");
  const std::string error = farm.client.watch(failing).error;
  EXPECT_EQ(error.find(dir / "data"), std::string::npos) << error;
  EXPECT_NE(error.find("cannot read the data folder/tiles/x/0.cpvt"), std::string::npos) << error;
}

// R9: a store error in the reaper thread (here: the database held by another writer past
// the busy timeout) called std::terminate; the coordinator must live on and serve.
TEST(Hardening, R9_AStoreThatFailsForAWhileDoesNotStopTheCoordinator) {
  TempDir dir("cpvs_r9");
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  server::Coordinator coordinator(config);
  sqlite3* other = nullptr;
  ASSERT_EQ(sqlite3_open((dir / "data/farm.sqlite").c_str(), &other), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(other, "BEGIN EXCLUSIVE", nullptr, nullptr, nullptr), SQLITE_OK);
  std::this_thread::sleep_for(std::chrono::milliseconds(5600));  // past the 5 s busy timeout
  sqlite3_exec(other, "COMMIT", nullptr, nullptr, nullptr);
  sqlite3_close(other);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // a reaper round after it
  EXPECT_FALSE(coordinator.scenes().uploadStatus(std::string(32, 'e')).known());  // still serving
}

// R4: an acknowledged tile whose file is gone at restart failed its whole job; now that
// tile is baked again and the job finishes.
TEST(Hardening, R4_AMissingAcknowledgedTileIsBakedAgainAtRestart) {
  TempDir dir("cpvs_r4");
  std::string jobId;
  {
    InProcessFarm farm(dir / "data");
    net::BakeSpec spec = farm.uploadAndSpec(dir / "box.obj", "city:1:1", "64");
    spec.options.tileSize = 32;  // 4 tiles
    jobId = farm.client.submit("r4", spec).jobId;
  }
  {
    // Tile 0 acknowledged, but its file lost (as after a power cut before R3's syncs).
    server::FarmStore store(dir / "data/farm.sqlite");
    ASSERT_TRUE(store.leaseNextTile("w", "l-lost", 1000, 1e15).has_value());
    ASSERT_TRUE(store.completeTile(jobId, 0));
  }
  InProcessFarm farm(dir / "data");
  worker::TileWorker tileWorker(testing::workerConfig(farm.connection(), dir / "cache"));
  std::thread workerThread([&] { tileWorker.run(); });
  const client::JobStatus done = farm.client.watch(jobId);
  tileWorker.stop();
  workerThread.join();
  EXPECT_EQ(done.state, client::JobState::Done) << done.error;
  EXPECT_EQ(done.tilesDone, 4u);
}

// R4: an acknowledged tile whose file is truncated or has a byte flipped when the
// coordinator restarts is baked again (that tile only), and the job gives the bytes of an
// undamaged run.
TEST(Hardening, R4_ATruncatedOrFlippedAcknowledgedTileIsBakedAgainAtRestart) {
  TempDir dir("cpvs_r4_damage");
  auto runJob = [&](const std::string& name, const std::function<void(const std::string& tileFile)>& damage) {
    const std::string data = dir / (name + ".data");
    std::string jobId;
    {
      InProcessFarm farm(data);
      net::BakeSpec spec = farm.uploadAndSpec(dir / "box.obj", "city:1:1", "64");
      spec.options.tileSize = 32;  // 4 tiles
      jobId = farm.client.submit("r4-" + name, spec).jobId;
      worker::TileWorker one(testing::workerConfig(farm.connection(), dir / (name + ".cache"), 1));
      one.run();  // one tile acknowledged, three to go
    }
    std::string acknowledged;
    for (const auto& e : fs::directory_iterator(data + "/tiles/" + jobId)) acknowledged = e.path().string();
    EXPECT_FALSE(acknowledged.empty());
    if (!acknowledged.empty()) damage(acknowledged);
    InProcessFarm farm(data);
    worker::TileWorker rest(testing::workerConfig(farm.connection(), dir / (name + ".cache")));
    std::thread pulling([&] { rest.run(); });
    const client::JobStatus done = farm.client.watch(jobId);
    rest.stop();
    pulling.join();
    EXPECT_EQ(done.state, client::JobState::Done) << name << ": " << done.error;
    farm.client.download(jobId, dir / (name + ".cpvs"));
    return readFile(dir / (name + ".cpvs"));
  };
  const std::vector<uint8_t> clean = runJob("clean", [](const std::string&) {});
  const std::vector<uint8_t> truncated = runJob("truncated", [](const std::string& f) {
    fs::resize_file(f, fs::file_size(f) / 2);
  });
  const std::vector<uint8_t> flipped = runJob("flipped", [](const std::string& f) {
    std::vector<uint8_t> b = readFile(f);
    b[b.size() / 2] ^= 0x10;
    writeFileAtomic(f, b);
  });
  EXPECT_EQ(truncated, clean);
  EXPECT_EQ(flipped, clean);
}

// R26: worker ids and failure reasons went into the log raw: a newline forged log lines.
TEST(Hardening, R26_WorkerTextCannotForgeLogLines) {
  EXPECT_EQ(loggable("a\nb\x1b[31m"), "a\\x0Ab\\x1B[31m");
  TempDir dir("cpvs_r26");
  InProcessFarm farm(dir / "data");
  farm.client.submit("r26", farm.uploadAndSpec(dir / "box.obj", "city:1:1", "64"));
  const std::string log = logOf([&] {
    const pb::TileLease lease = farm.coordinator.leases().lease("w\n[2026-01-01 00:00:00.000] [info] job jX done");
    ASSERT_TRUE(lease.granted());
    farm.coordinator.leases().failTile(lease.lease_id(), "bad\n[2026-01-01 00:00:00.000] [info] all good");
  });
  std::istringstream lines(log);
  std::string line;
  int warnings = 0;
  while (std::getline(lines, line)) {
    EXPECT_NE(line.rfind("[2026-01-01", 0), 0u) << "a forged line: " << line;
    warnings += line.find("given back by w\\x0A[2026-01-01") != std::string::npos;
  }
  EXPECT_EQ(warnings, 1) << log;
}

// R23: the worker built cache paths from the lease's scene_hash unchecked; a coordinator
// (or a man in the middle) granting "../../x" made it write outside its cache.
class OneBadLease final : public pb::Workers::Service {
 public:
  grpc::Status LeaseTile(grpc::ServerContext*, const pb::LeaseRequest*, pb::TileLease* out) override {
    std::lock_guard lock(mutex);
    if (granted++ > 0) {
      out->set_granted(false);
      out->set_retry_after_ms(50);
      return grpc::Status::OK;
    }
    OrthoGrid g;
    g.frame = LightFrame::fromDirection({0, -1, 0});
    g.log2Resolution = 6;
    out->set_granted(true);
    out->set_lease_id("l-bad");
    out->set_job_id("j");
    out->set_scene_hash("../../escaped");
    *out->mutable_grid() = net::toProto(gridSpecOf(g));
    *out->mutable_options() = net::toProto(BakeOptions{});
    out->set_deadline_unix_ms(std::chrono::duration_cast<std::chrono::milliseconds>(
                                  std::chrono::system_clock::now().time_since_epoch()).count() + 60000);
    return grpc::Status::OK;
  }
  grpc::Status FailTile(grpc::ServerContext*, const pb::FailRequest* req, pb::FailReply*) override {
    std::lock_guard lock(mutex);
    reasons.push_back(req->reason());
    return grpc::Status::OK;
  }
  grpc::Status RenewLease(grpc::ServerContext*, const pb::RenewRequest*, pb::RenewReply* out) override {
    out->set_valid(true);
    return grpc::Status::OK;
  }
  std::mutex mutex;
  int granted = 0;
  std::vector<std::string> reasons;
};

TEST(Hardening, R23_AWorkerRefusesASceneHashThatIsNotAHash) {
  TempDir dir("cpvs_r23");
  OneBadLease service;
  {
    ServiceServer server(service);
    worker::TileWorker tileWorker(testing::workerConfig(server.connection(), dir / "a/b/cache", 1));
    tileWorker.run();  // returns after its one tile
  }
  EXPECT_FALSE(fs::exists(dir / "a/escaped.part"));
  EXPECT_FALSE(fs::exists(dir / "a/escaped"));
  ASSERT_EQ(service.reasons.size(), 1u);
  EXPECT_NE(service.reasons[0].find("scene_hash"), std::string::npos) << service.reasons[0];
}

// R12: a hung bake renewed its lease forever; renewals now stop after --max-tile-seconds.
TEST(Hardening, R12_RenewalsEndAfterTheLongestATileMayTake) {
  TempDir dir("cpvs_r12");
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  config.leaseSeconds = 1;
  config.maxTileSeconds = 2;
  config.maxAttempts = 5;
  InProcessFarm farm(config);
  farm.client.submit("r12", farm.uploadAndSpec(dir / "box.obj", "city:1:1", "64"));
  server::LeaseService& leases = farm.coordinator.leases();
  const pb::TileLease first = leases.lease("hung");
  ASSERT_TRUE(first.granted());
  const auto start = std::chrono::steady_clock::now();
  bool stillValid = true;
  while (stillValid && std::chrono::steady_clock::now() - start < std::chrono::seconds(5)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    stillValid = leases.renew(first.lease_id()).valid();
  }
  const double refusedAfter = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_FALSE(stillValid);
  EXPECT_GT(refusedAfter, 1.5);  // renewals past the lease's own length were honoured...
  EXPECT_LT(refusedAfter, 3.0);  // ...until the tile's 2 s were up
  // The reaper returns the tile; another worker gets it.
  pb::TileLease second;
  while (!second.granted() && std::chrono::steady_clock::now() - start < std::chrono::seconds(8)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    second = leases.lease("healthy");
  }
  EXPECT_TRUE(second.granted());
  EXPECT_EQ(second.tile_index(), first.tile_index());
}

// Answers the first CompleteTile with UNAVAILABLE, as a coordinator that restarts under
// the worker would, and forwards the rest.
class FlakyOnce final : public ForwardingWorkers {
 public:
  using ForwardingWorkers::ForwardingWorkers;
  grpc::Status CompleteTile(grpc::ServerContext*, grpc::ServerReader<pb::TileResultChunk>* reader,
                            pb::CompleteReply* out) override {
    std::vector<pb::TileResultChunk> chunks;
    pb::TileResultChunk chunk;
    while (reader->Read(&chunk)) chunks.push_back(chunk);
    if (completes++ == 0) return grpc::Status(grpc::StatusCode::UNAVAILABLE, "restarting");
    return forwardResult(chunks, out);
  }
  std::atomic<int> completes{0};
};

// R17: a worker whose CompleteTile met UNAVAILABLE threw its baked tile away (the tile was
// baked again after its lease expired); now it sends it again.
TEST(Hardening, R17_ABakedTileIsSentAgainNotBakedAgain) {
  TempDir dir("cpvs_r17");
  InProcessFarm farm(dir / "data");
  const std::string jobId = farm.client.submit("r17", farm.uploadAndSpec(dir / "box.obj", "city:1:1", "64")).jobId;
  FlakyOnce proxy(farm.server.address());
  uint64_t tilesDone = 0;
  const std::string log = logOf([&] {
    ServiceServer proxyServer(proxy);
    worker::TileWorker tileWorker(testing::workerConfig(proxyServer.connection(), dir / "cache", 1));
    tileWorker.run();  // one tile, delivered on the second try
    tilesDone = tileWorker.tilesDone();
  });
  EXPECT_EQ(proxy.completes.load(), 2);
  ASSERT_EQ(tilesDone, 1u);  // before the watch, which would wait for the tile
  const client::JobStatus status = farm.client.watch(jobId);
  EXPECT_EQ(status.state, client::JobState::Done) << status.error;
  size_t bakes = 0;
  for (size_t at = log.find(": baking"); at != std::string::npos; at = log.find(": baking", at + 1)) ++bakes;
  EXPECT_EQ(bakes, 1u) << log;
}

// Shows the worker a deadline five minutes later than the coordinator's (a worker clock
// five minutes behind), with or without the lease's length, and counts renewals. With
// `holdResult`, a finished tile's result is held back until `holdResult` renewals have
// passed (a slow tile on any machine; the worker renews while its result is sent), at
// most `maxHold`.
class SkewedClock final : public ForwardingWorkers {
 public:
  SkewedClock(const std::string& address, bool sendLength, int holdResult = 0,
              std::chrono::milliseconds maxHold = std::chrono::seconds(20))
      : ForwardingWorkers(address), sendLength_(sendLength), holdResult_(holdResult), maxHold_(maxHold) {}
  grpc::Status LeaseTile(grpc::ServerContext* ctx, const pb::LeaseRequest* req, pb::TileLease* out) override {
    grpc::Status s = ForwardingWorkers::LeaseTile(ctx, req, out);
    out->set_deadline_unix_ms(out->deadline_unix_ms() + 300000);
    if (!sendLength_) out->clear_lease_ms();
    return s;
  }
  grpc::Status RenewLease(grpc::ServerContext* ctx, const pb::RenewRequest* req, pb::RenewReply* out) override {
    ++renewals;
    grpc::Status s = ForwardingWorkers::RenewLease(ctx, req, out);
    out->set_deadline_unix_ms(out->deadline_unix_ms() + 300000);
    if (!sendLength_) out->clear_lease_ms();
    return s;
  }
  grpc::Status CompleteTile(grpc::ServerContext*, grpc::ServerReader<pb::TileResultChunk>* reader,
                            pb::CompleteReply* out) override {
    std::vector<pb::TileResultChunk> chunks;
    pb::TileResultChunk chunk;
    while (reader->Read(&chunk)) chunks.push_back(chunk);
    const int from = renewals.load();
    const auto until = std::chrono::steady_clock::now() + maxHold_;
    while (renewals.load() - from < holdResult_ && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    renewalsWhileHeld = renewals.load() - from;
    return forwardResult(chunks, out);
  }
  std::atomic<int> renewals{0};
  std::atomic<int> renewalsWhileHeld{0};

 private:
  bool sendLength_;
  int holdResult_;
  std::chrono::milliseconds maxHold_;
};

// R11: the worker's renewal period came from the coordinator's wall-clock deadline minus
// its own clock; five minutes of skew meant no renewal within a 0.3 s lease. The proxy
// holds the tile's result for three renewals (at most 20 s, 66 lease periods): a worker
// that renews from the skewed deadline would let the lease expire first.
TEST(Hardening, R11_RenewalsFollowTheLeaseLengthWhateverTheClocks) {
  TempDir dir("cpvs_r11");
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  config.leaseSeconds = 0.3;  // renewals every 0.1 s
  InProcessFarm farm(config);
  net::BakeSpec spec = farm.uploadAndSpec(dir / "city.obj", "city:3:2", "256");
  spec.options.tileSize = 256;  // one tile
  const std::string jobId = farm.client.submit("r11", spec).jobId;

  SkewedClock proxy(farm.server.address(), true, 3);
  {
    ServiceServer proxyServer(proxy);
    worker::TileWorker tileWorker(testing::workerConfig(proxyServer.connection(), dir / "cache", 1));
    tileWorker.run();
  }
  EXPECT_GE(proxy.renewalsWhileHeld.load(), 3);
  const client::JobStatus status = farm.client.watch(jobId);
  EXPECT_EQ(status.tilesDone, 1u);  // the lease held to the end
  EXPECT_EQ(status.state, client::JobState::Done) << status.error;
}

// R10: a worker that failed every tile at once took the lowest queued tile again each time
// and burnt its three attempts in milliseconds while a healthy worker was busy. A tile
// now goes to another worker first, and a worker that fails three in a row is kept from
// tiles for a while.
TEST(Hardening, R10_ABadWorkerCannotBurnATilesAttempts) {
  TempDir dir("cpvs_r10_bad");
  InProcessFarm farm(dir / "data");
  net::BakeSpec spec = farm.uploadAndSpec(dir / "city.obj", "city:3:2", "128");
  spec.options.tileSize = 64;  // 4 tiles
  const std::string jobId = farm.client.submit("r10-bad", spec).jobId;
  server::LeaseService& leases = farm.coordinator.leases();
  std::atomic<bool> stop{false};
  std::atomic<int> failed{0};
  std::string log;
  client::JobStatus status;
  log = logOf([&] {
    std::thread bad([&] {
      while (!stop) {
        const pb::TileLease l = leases.lease("bad");
        if (!l.granted()) {
          std::this_thread::sleep_for(std::chrono::milliseconds(1));
          continue;
        }
        leases.failTile(l.lease_id(), "broken at once");
        ++failed;
      }
    });
    while (failed < 3) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    worker::TileWorker healthy(testing::workerConfig(farm.connection(), dir / "cache"));
    std::thread pulling([&] { healthy.run(); });
    status = farm.client.watch(jobId);
    healthy.stop();
    stop = true;
    pulling.join();
    bad.join();
  });
  EXPECT_EQ(status.state, client::JobState::Done) << status.error;
  EXPECT_EQ(failed.load(), 3);  // then quarantined for the rest of the job
  EXPECT_GT(leases.quarantinedForMs("bad"), 20000);
  EXPECT_NE(log.find("worker bad gets no tile for 30 s: it failed 3 tiles in a row"), std::string::npos) << log;
}

// R10: a worker that stops mid-tile (preempted, scaled down) gives its tile back without
// costing it an attempt; the worker's own trouble keeps that worker away instead.
TEST(Hardening, R10_AWorkerThatStopsOrBreaksCostsTheTileNoAttempt) {
  TempDir dir("cpvs_r10_kinds");
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  config.maxAttempts = 1;
  InProcessFarm farm(config);
  const std::string jobId = farm.client.submit("r10-kinds", farm.uploadAndSpec(dir / "box.obj", "city:1:1", "64")).jobId;
  server::LeaseService& leases = farm.coordinator.leases();
  for (int i = 0; i < 2; ++i) {
    const pb::TileLease l = leases.lease("preempted-" + std::to_string(i));
    ASSERT_TRUE(l.granted());
    leases.failTile(l.lease_id(), "worker stopping", pb::FAIL_INTERRUPTED);
    EXPECT_EQ(leases.quarantinedForMs("preempted-" + std::to_string(i)), 0);
  }
  const pb::TileLease broken = leases.lease("full-disk");
  ASSERT_TRUE(broken.granted());
  leases.failTile(broken.lease_id(), "fetching scene: No space left on device", pb::FAIL_WORKER);
  EXPECT_GT(leases.quarantinedForMs("full-disk"), 20000);
  const pb::TileLease kept = leases.lease("full-disk");
  EXPECT_FALSE(kept.granted());
  EXPECT_GT(kept.retry_after_ms(), 0u);
  EXPECT_EQ(farm.client.list(true).at(0).state, client::JobState::Running);
  worker::TileWorker healthy(testing::workerConfig(farm.connection(), dir / "cache", 1));
  healthy.run();
  EXPECT_EQ(farm.client.watch(jobId).state, client::JobState::Done);
}

// R10: leases out when the coordinator went down were expired at its first round after
// the restart (their deadlines had passed while nobody could renew), each an attempt.
TEST(Hardening, R10_LeasesOutAcrossARestartGetAWholeLeaseLength) {
  TempDir dir("cpvs_r10_restart");
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  config.leaseSeconds = 1;
  config.maxAttempts = 1;
  std::string leaseId;
  {
    InProcessFarm farm(config);
    farm.client.submit("r10-restart", farm.uploadAndSpec(dir / "box.obj", "city:1:1", "64"));
    const pb::TileLease l = farm.coordinator.leases().lease("survivor");
    ASSERT_TRUE(l.granted());
    leaseId = l.lease_id();
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(2000));  // the lease's deadline passes while down
  InProcessFarm farm(config);
  std::this_thread::sleep_for(std::chrono::milliseconds(600));  // two reaper rounds
  EXPECT_TRUE(farm.coordinator.leases().renew(leaseId).valid());
  EXPECT_EQ(farm.client.list(true).at(0).state, client::JobState::Running) << farm.client.list(true).at(0).error;
}

// R4: a worker's "the scene arrived damaged" was a failed tile attempt; the coordinator now
// checks its own copy: intact, the worker is kept away and nothing is counted; damaged,
// the copy is forgotten and the job fails saying what to do, and an upload stores it again.
TEST(Hardening, R4_ASceneDamagedOnTheCoordinatorIsForgottenAndUploadedAgain) {
  TempDir dir("cpvs_r4_scene");
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  config.maxAttempts = 1;
  InProcessFarm farm(config);
  const net::BakeSpec spec = farm.uploadAndSpec(dir / "box.obj", "city:1:1", "64");
  const std::string jobId = farm.client.submit("r4-scene", spec).jobId;
  server::LeaseService& leases = farm.coordinator.leases();
  const pb::TileLease first = leases.lease("w1");
  ASSERT_TRUE(first.granted());
  leases.failTile(first.lease_id(), "scene arrived damaged (hash mismatch)", pb::FAIL_SCENE_DAMAGED);
  EXPECT_EQ(farm.client.list(true).at(0).state, client::JobState::Running);  // intact here: the transfer's fault
  EXPECT_GT(leases.quarantinedForMs("w1"), 0);

  const std::string stored = dir / ("data/scenes/" + spec.sceneHash + ".obj");
  ASSERT_TRUE(fs::exists(stored));
  std::vector<uint8_t> bytes = readFile(stored);
  bytes[bytes.size() / 2] ^= 0x20;
  writeFileAtomic(stored, bytes);
  const pb::TileLease second = leases.lease("w2");
  ASSERT_TRUE(second.granted());
  leases.failTile(second.lease_id(), "scene arrived damaged (hash mismatch)", pb::FAIL_SCENE_DAMAGED);
  const client::JobStatus failed = farm.client.watch(jobId);
  EXPECT_EQ(failed.state, client::JobState::Failed);
  EXPECT_NE(failed.error.find("submit the job again"), std::string::npos) << failed.error;
  EXPECT_FALSE(farm.coordinator.scenes().uploadStatus(spec.sceneHash).complete());
  const client::FarmClient::UploadResult again = farm.client.uploadScene(dir / "box.obj");
  EXPECT_FALSE(again.alreadyThere);
  const std::string retried = farm.client.submit("r4-scene-again", spec).jobId;
  worker::TileWorker healthy(testing::workerConfig(farm.connection(), dir / "cache", 1));
  healthy.run();
  EXPECT_EQ(farm.client.watch(retried).state, client::JobState::Done);
}

// R23 (rest): a worker trusted any cached file named after a scene's hash; one damaged on
// its disk is now fetched again, not baked.
TEST(Hardening, R23_ADamagedCachedSceneIsFetchedAgain) {
  TempDir dir("cpvs_r23_cache");
  InProcessFarm farm(dir / "data");
  const net::BakeSpec spec = farm.uploadAndSpec(dir / "box.obj", "city:1:1", "64");
  const std::string jobId = farm.client.submit("r23-cache", spec).jobId;
  fs::create_directories(dir / "cache");
  std::ofstream(dir / ("cache/" + spec.sceneHash + ".obj")) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const std::string log = logOf([&] {
    worker::TileWorker w(testing::workerConfig(farm.connection(), dir / "cache", 1));
    w.run();
  });
  EXPECT_NE(log.find("fails its hash: fetching it again"), std::string::npos) << log;
  EXPECT_EQ(farm.client.watch(jobId).state, client::JobState::Done);
  const std::vector<uint8_t> cached = readFile(dir / ("cache/" + spec.sceneHash + ".obj"));
  EXPECT_EQ(contentHash(cached.data(), cached.size()).hex(), spec.sceneHash);
}

// R19: announcing a scene's hash with another file name wiped the upload in progress,
// and two clients uploading one scene at once made the second fail.
TEST(Hardening, R19_OneClientCannotWipeAnothersUploadOfTheSameScene) {
  TempDir dir("cpvs_r19");
  InProcessFarm farm(dir / "data");
  const std::string obj = dir / "city.obj";
  writeObj(obj, openScene("city:4:4"));
  {
    std::ofstream more(obj, std::ios::app);  // comments, to span several chunks
    for (int i = 0; i < 50000; ++i) more << "# padding line " << i << " of a scene larger than three upload chunks\n";
  }
  const std::vector<uint8_t> bytes = readFile(obj);
  ASSERT_GT(bytes.size(), 3 * net::kChunkBytes);
  const std::string hash = contentHash(bytes.data(), bytes.size()).hex();
  pb::UploadSceneChunk first;
  first.set_scene_hash(hash);
  first.set_file_name("city.obj");
  first.set_total_size(bytes.size());
  first.set_offset(0);
  server::SceneStore& scenes = farm.coordinator.scenes();
  scenes.beginUpload(first);
  scenes.appendUpload(hash, 0, std::string(bytes.begin(), bytes.begin() + 1000));
  // The same file under another name carries on from there.
  pb::UploadSceneChunk renamed = first;
  renamed.set_file_name("town.obj");
  renamed.set_offset(1000);
  EXPECT_NO_THROW(scenes.beginUpload(renamed));
  EXPECT_EQ(scenes.uploadStatus(hash).received(), 1000u);
  // Another size (or format) for the same hash is refused while the upload moves.
  pb::UploadSceneChunk liar = first;
  liar.set_total_size(bytes.size() + 1);
  try {
    scenes.beginUpload(liar);
    ADD_FAILURE() << "another size wiped the upload in progress";
  } catch (const net::FarmError& e) {
    EXPECT_EQ(e.kind, net::ErrorKind::FailedPrecondition) << e.what();
  }
  pb::UploadSceneChunk otherFormat = first;
  otherFormat.set_file_name("city.ply");
  EXPECT_THROW(scenes.beginUpload(otherFormat), net::FarmError);
  EXPECT_EQ(scenes.uploadStatus(hash).received(), 1000u);
  // Two clients at once: both succeed, one of them finding the scene stored.
  client::FarmClient a(farm.connection()), b(farm.connection());
  client::FarmClient::UploadResult ra, rb;
  std::string errors;
  std::mutex errorsMutex;
  auto upload = [&](client::FarmClient& c, client::FarmClient::UploadResult& r) {
    try {
      r = c.uploadScene(obj);
    } catch (const std::exception& e) {
      std::lock_guard lock(errorsMutex);
      errors += std::string(e.what()) + "\n";
    }
  };
  std::thread ta([&] { upload(a, ra); });
  std::thread tb([&] { upload(b, rb); });
  ta.join();
  tb.join();
  EXPECT_EQ(errors, "");
  EXPECT_EQ(ra.sceneHash, hash);
  EXPECT_EQ(rb.sceneHash, hash);
  EXPECT_TRUE(scenes.uploadStatus(hash).complete());
}

/// A one-triangle glTF whose only buffer is `uri` of `byteLength` bytes.
std::string gltfWithBuffer(const std::string& uri, uint64_t byteLength) {
  return R"({"asset":{"version":"2.0"},"buffers":[{"uri":")" + uri + R"(","byteLength":)" + std::to_string(byteLength) +
         R"(}],"bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36}],"accessors":[{"bufferView":0,)"
         R"("componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}],)"
         R"("meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}],"scene":0})";
}

/// A coordinator that imports uploads the way cpvs-server does: in a limited child process.
server::CoordinatorConfig isolatedImports(const std::string& dataDir, double seconds = 60, uint64_t memoryMb = 2048) {
  server::CoordinatorConfig config;
  config.dataDir = dataDir;
  config.import.helper = CPVS_IMPORT;
  config.import.seconds = seconds;
  config.import.memoryBytes = memoryMb << 20;
  return config;
}

/// The error an upload of `path` gets; empty when it is stored.
std::string uploadError(client::FarmClient& client, const std::string& path, net::ErrorKind* kind = nullptr) {
  try {
    client.uploadScene(path);
    return "";
  } catch (const client::FarmCallError& e) {
    if (kind) *kind = e.kind();
    return e.what();
  }
}

// R6: an uploaded glTF whose buffer named a file outside the upload ("../farm.sqlite",
// "/dev/zero" with 2 GiB) made the coordinator's assimp open it. Only the uploaded file
// can be opened now, in the child process and in-process alike; a buffer embedded as a
// data: URI imports.
TEST(Hardening, R6_ASceneThatRefersToOtherFilesIsRefused) {
  TempDir dir("cpvs_r6_refs");
  for (const bool isolated : {true, false}) {
    SCOPED_TRACE(isolated ? "in the import helper" : "in process");
    const std::string data = dir / (isolated ? "isolated" : "in-process");
    InProcessFarm farm(isolated ? isolatedImports(data) : [&] {
      server::CoordinatorConfig c;
      c.dataDir = data;
      return c;
    }());
    for (const auto& [name, uri, length] :
         std::vector<std::tuple<std::string, std::string, uint64_t>>{{"db.gltf", "../farm.sqlite", 36},
                                                                      {"zero.gltf", "../../../../../../dev/zero", 1ull << 31}}) {
      std::ofstream(dir / name) << gltfWithBuffer(uri, length);
      net::ErrorKind kind{};
      const auto start = std::chrono::steady_clock::now();
      const std::string error = uploadError(farm.client, dir / name, &kind);
      EXPECT_EQ(kind, net::ErrorKind::InvalidArgument) << error;
      EXPECT_NE(error.find("external references are not allowed"), std::string::npos) << error;
      EXPECT_EQ(error.find(data), std::string::npos) << "names the data folder: " << error;
      EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 10.0);
    }
    std::ofstream(dir / "embedded.gltf")
        << gltfWithBuffer("data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA", 36);
    EXPECT_EQ(uploadError(farm.client, dir / "embedded.gltf"), "");
  }
}

// R6: the importer crashing, hanging or eating memory on an upload took the coordinator
// with it (it ran in-process). Now each costs that upload only, which starts over, and
// other uploads go on meanwhile.
TEST(Hardening, R6_AnImportThatCrashesHangsOrBlowsUpCostsItsUploadOnly) {
  TempDir dir("cpvs_r6_child");
  InProcessFarm farm(isolatedImports(dir / "data", 3, 512));
  const std::string obj = dir / "box.obj";
  writeObj(obj, openScene("city:1:1"));
  const std::vector<uint8_t> bytes = readFile(obj);
  const std::string hash = contentHash(bytes.data(), bytes.size()).hex();
  struct Case {
    const char* point;
    const char* words;
  };
  for (const Case& c : {Case{"import-crash", "the importer crashed on the file (signal 11"},
                        Case{"import-hog", "needs more than its 512 MiB"},
                        Case{"import-hang", "took longer than 3 s"}}) {
    SCOPED_TRACE(c.point);
    ::setenv("CPVS_FAILPOINT", (std::string(c.point) + ":" + hash).c_str(), 1);
    std::string other;
    std::thread meanwhile;
    if (std::string(c.point) == "import-hang") {
      // Another scene uploads while this one hangs in its import.
      meanwhile = std::thread([&] {
        const std::string town = dir / "town.obj";
        writeObj(town, openScene("city:2:1"));
        const auto start = std::chrono::steady_clock::now();
        other = uploadError(farm.client, town);
        if (other.empty() && std::chrono::steady_clock::now() - start > std::chrono::milliseconds(2500))
          other = "waited for the hanging import";
      });
    }
    net::ErrorKind kind{};
    const std::string error = uploadError(farm.client, obj, &kind);
    if (meanwhile.joinable()) meanwhile.join();
    ::unsetenv("CPVS_FAILPOINT");
    EXPECT_EQ(kind, net::ErrorKind::InvalidArgument) << error;
    EXPECT_NE(error.find(c.words), std::string::npos) << error;
    EXPECT_EQ(other, "");
    const pb::UploadStatus status = farm.coordinator.scenes().uploadStatus(hash);
    EXPECT_FALSE(status.complete());
    EXPECT_EQ(status.received(), 0u);  // starts over
  }
  EXPECT_EQ(uploadError(farm.client, obj), "");
  // The mesh kept at upload serves every submit: with the importer broken, submits work.
  ::setenv("CPVS_FAILPOINT", "import-crash", 1);
  net::BakeSpec spec;
  spec.sceneHash = hash;
  spec.sun = Vec3{0.2, -1, 0.1};
  spec.resolution = "64";
  const client::JobStatus job = farm.client.submit("r6-no-import", spec);
  ::unsetenv("CPVS_FAILPOINT");
  EXPECT_NE(job.state, client::JobState::Failed) << job.error;
  EXPECT_TRUE(fs::exists(dir / ("data/scenes/" + hash + ".mesh")));
}

// The scene mesh file the importer sends back and the coordinator keeps is untrusted
// input: every damage is refused, and a round trip keeps the geometry's hash.
TEST(Hardening, R6_ASceneMeshFileRoundTripsAndDamageIsRefused) {
  SceneStats stats;
  Scene scene = openScene("city:2:2");
  stats = finalizeScene(scene);
  scene.lights.push_back(SceneLight{"sun", SceneLight::Type::Directional, {0, 10, 0}, {0, -1, 0}, {1, 1, 1}, 0, 0, 0, {}, {}});
  scene.lights.push_back(SceneLight{"panel", SceneLight::Type::Area, {5, 9, 5}, {0, -1, 0}, {1, 1, 1}, 0, 0, 0, {2, 0, 0}, {0, 0, 3}});
  scene.lights.push_back(SceneLight{"lamp", SceneLight::Type::Spot, {1, 2, 3}, {0, -1, 0}, {2, 1, 1}, 20, 30, 12.5, {}, {}});
  scene.media.push_back(SceneMedium{"fog", 0.25});
  const uint32_t half = uint32_t(scene.triangleCount() / 2);
  scene.meshes = {{"city", "blocks", "stone", 0, half, {0, 0, 0}},
                  {"lampNode", "", "glass", half, uint32_t(scene.triangleCount()) - half, {0.75f, 0.5f, 0.25f}}};
  const std::vector<uint8_t> bytes = encodeSceneMesh(scene, stats);
  SceneStats back;
  const Scene decoded = decodeSceneMesh(bytes.data(), bytes.size(), "mesh", &back);
  EXPECT_EQ(sceneHash(decoded), sceneHash(scene));
  ASSERT_EQ(decoded.lights.size(), scene.lights.size()) << "the city's street lamps, the sun, a panel and a lamp";
  EXPECT_EQ(decoded.lights.back().name, "lamp");
  EXPECT_EQ(decoded.lights.back().range, 12.5) << "a bundle planned from the stored mesh reaches as far as the file's";
  EXPECT_EQ(decoded.lights.back().outerConeDeg, 30);
  EXPECT_EQ(decoded.lights[decoded.lights.size() - 2].edgeV, (Vec3{0, 0, 3})) << "an area light keeps its rectangle";
  ASSERT_EQ(decoded.media.size(), 1u);
  EXPECT_EQ(decoded.media[0].material, "fog");
  EXPECT_EQ(decoded.media[0].absorption, 0.25);
  EXPECT_EQ(back.closedParts, stats.closedParts);
  ASSERT_EQ(decoded.meshes.size(), 2u) << "a fixture named in a bundle is found in the stored mesh";
  EXPECT_EQ(decoded.meshes[1].node, "lampNode");
  EXPECT_EQ(decoded.meshes[1].material, "glass");
  EXPECT_EQ(decoded.meshes[1].firstTriangle, half);
  EXPECT_EQ(decoded.meshes[1].transmittance, (std::array<float, 3>{0.75f, 0.5f, 0.25f})) << "its glass stays glass";
  EXPECT_FALSE(isTranslucent(decoded.meshes[0]));
  // Meshes that do not cover the triangles in order are refused, the checksum resealed.
  // So is a transmittance outside [0, 1].
  for (int way = 0; way < 3; ++way) {
    Scene wrong = scene;
    if (way == 0) wrong.meshes[1].firstTriangle += 1;
    else if (way == 1) wrong.meshes[1].triangles -= 1;
    else wrong.meshes[1].transmittance[2] = std::nanf("");
    std::vector<uint8_t> b = encodeSceneMesh(wrong, stats);
    EXPECT_NE(testing::inputErrorOf([&] { decodeSceneMesh(b.data(), b.size(), "mesh"); })
                  .find(std::array<const char*, 3>{"a mesh starts", "its meshes hold", "transmittance is outside"}[way]),
              std::string::npos);
  }
  for (size_t at : {size_t(0), size_t(9), size_t(60), bytes.size() / 2, bytes.size() - 1}) {
    std::vector<uint8_t> bad = bytes;
    bad[at] ^= 0x01;
    EXPECT_THROW(decodeSceneMesh(bad.data(), bad.size(), "mesh"), FormatError) << "byte " << at;
  }
  for (size_t size : {size_t(0), size_t(7), size_t(40), bytes.size() - 1})
    EXPECT_THROW(decodeSceneMesh(bytes.data(), size, "mesh"), FormatError) << "cut to " << size;

  // A name longer than a mesh file keeps is cut at finalize, so the stored mesh hashes as the scene.
  Scene named = scene;
  named.meshes[0].node = std::string(5000, 'n');
  const SceneStats namedStats = finalizeScene(named);
  EXPECT_EQ(named.meshes[0].node.size(), kMaxMeshNameBytes);
  const std::vector<uint8_t> namedBytes = encodeSceneMesh(named, namedStats);
  EXPECT_EQ(sceneHash(decodeSceneMesh(namedBytes.data(), namedBytes.size(), "mesh")), sceneHash(named));
}

// R15: every WatchJob held a server thread with no bound; 1,000 of them took the
// coordinator's threads and workers could no longer lease. Streams past the cap are
// refused at once; the coordinator keeps serving clients and workers.
TEST(Hardening, R15_AThousandWatchesAreCappedAndWorkersStillGetThrough) {
  TempDir dir("cpvs_r15_watch");
  InProcessFarm farm(dir / "data");
  const std::string jobId = farm.client.submit("r15", farm.uploadAndSpec(dir / "box.obj", "city:1:1", "64")).jobId;
  constexpr int kWatches = 1000, kChannels = 10;
  std::vector<std::unique_ptr<pb::Farm::Stub>> stubs;
  for (int c = 0; c < kChannels; ++c) {
    grpc::ChannelArguments args;
    args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);  // a connection each
    args.SetInt("cpvs.test.channel", c);
    stubs.push_back(pb::Farm::NewStub(
        grpc::CreateCustomChannel(farm.server.address(), grpc::InsecureChannelCredentials(), args)));
  }
  struct Watch {
    grpc::ClientContext ctx;
    std::unique_ptr<grpc::ClientAsyncReader<pb::JobStatus>> reader;
    pb::JobStatus first;
    grpc::Status status;
  };
  grpc::CompletionQueue cq;
  std::vector<std::unique_ptr<Watch>> watches;
  pb::JobRef ref;
  ref.set_job_id(jobId);
  // Tags: index * 4 + phase (0 started, 1 read, 2 finished).
  for (int i = 0; i < kWatches; ++i) {
    watches.push_back(std::make_unique<Watch>());
    Watch& w = *watches.back();
    w.reader = stubs[size_t(i % kChannels)]->PrepareAsyncWatchJob(&w.ctx, ref, &cq);
    w.reader->StartCall(reinterpret_cast<void*>(intptr_t(i) * 4));
  }
  int open = 0, refused = 0, other = 0, finished = 0;
  const auto deadline = std::chrono::system_clock::now() + std::chrono::seconds(60);
  while (open + finished < kWatches) {
    void* tag;
    bool ok;
    if (cq.AsyncNext(&tag, &ok, deadline) != grpc::CompletionQueue::GOT_EVENT) break;
    const intptr_t i = reinterpret_cast<intptr_t>(tag) / 4, phase = reinterpret_cast<intptr_t>(tag) % 4;
    Watch& w = *watches[size_t(i)];
    if (phase == 0 && ok) {
      w.reader->Read(&w.first, reinterpret_cast<void*>(i * 4 + 1));
    } else if (phase == 1 && ok) {
      ++open;  // a first status arrived: the stream is held
    } else if (phase <= 1) {
      w.reader->Finish(&w.status, reinterpret_cast<void*>(i * 4 + 2));
    } else {
      ++finished;
      ++(w.status.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED ? refused : other);
    }
  }
  EXPECT_EQ(open, 256);
  EXPECT_EQ(refused, kWatches - 256);
  EXPECT_EQ(other, 0);
  // Clients and workers still get answers while the 256 are held.
  EXPECT_EQ(farm.client.list(false).size(), 1u);
  EXPECT_TRUE(farm.coordinator.leases().lease("w").granted());
  auto workers = pb::Workers::NewStub(net::makeChannel(farm.connection()));
  grpc::ClientContext leaseCtx;
  leaseCtx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  pb::LeaseRequest lr;
  lr.set_worker_id("w2");
  pb::TileLease lease;
  EXPECT_TRUE(workers->LeaseTile(&leaseCtx, lr, &lease).ok());
  for (auto& w : watches) w->ctx.TryCancel();
  cq.Shutdown();
  void* tag;
  bool ok;
  while (cq.Next(&tag, &ok)) {
    const intptr_t i = reinterpret_cast<intptr_t>(tag) / 4, phase = reinterpret_cast<intptr_t>(tag) % 4;
    if (phase == 1 && ok) watches[size_t(i)]->reader->Finish(&watches[size_t(i)]->status, reinterpret_cast<void*>(i * 4 + 2));
  }
}

// R15: uploads that were started and never finished piled up without bound (each a
// .part file and a row). Past the quota the idle ones make room; with none idle, a new
// upload is refused and the ones in progress are untouched.
TEST(Hardening, R15_PendingUploadsHaveAQuota) {
  TempDir dir("cpvs_r15_uploads");
  auto start = [&](server::SceneStore& scenes, int i) {
    pb::UploadSceneChunk first;
    char hash[33];
    std::snprintf(hash, sizeof hash, "%032x", i + 1);
    first.set_scene_hash(hash);
    first.set_file_name("s.obj");
    first.set_total_size(1000);
    first.set_offset(0);
    scenes.beginUpload(first);
    scenes.appendUpload(hash, 0, "v 0 0 0\n");
  };
  {
    InProcessFarm farm(dir / "data");
    int refused = 0;
    for (int i = 0; i < 200; ++i) {
      try {
        start(farm.coordinator.scenes(), i);
      } catch (const net::FarmError& e) {
        EXPECT_EQ(e.kind, net::ErrorKind::ResourceExhausted) << e.what();
        ++refused;
      }
    }
    EXPECT_EQ(refused, 200 - 64);
    EXPECT_EQ(farm.coordinator.scenes().uploadStatus(std::string(31, '0') + "1").received(), 8u);  // kept
  }
  // After a restart none of them is known to move: a new upload makes room by dropping idle ones.
  InProcessFarm farm(dir / "data");
  EXPECT_NO_THROW(start(farm.coordinator.scenes(), 500));
  EXPECT_FALSE(farm.coordinator.scenes().uploadStatus(std::string(31, '0') + "1").known());
  size_t parts = 0;
  for (const auto& e : fs::directory_iterator(dir / "data/scenes")) parts += e.path().extension() == ".part";
  EXPECT_EQ(parts, 1u);
}

// R15: one client could take every one of the farm's unfinished-job places, and every
// other client was refused. A client (an owner) holds at most its share.
TEST(Hardening, R15_OneClientCannotTakeEveryJobPlace) {
  TempDir dir("cpvs_r15_per_client");
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  config.maxActiveJobs = 4;
  config.maxActiveJobsPerClient = 2;
  InProcessFarm farm(config);
  const net::BakeSpec spec = farm.uploadAndSpec(dir / "box.obj", "city:1:1", "64");
  auto submitAs = [&](const server::Access& access, const std::string& requestId) {
    return farm.coordinator.jobs().submit(requestId, spec, access);
  };
  const server::Access alice = server::Access::of("alice"), bob = server::Access::of("bob");
  submitAs(alice, "a1");
  submitAs(alice, "a2");
  try {
    submitAs(alice, "a3");
    ADD_FAILURE() << "a third job of one client was taken";
  } catch (const net::FarmError& e) {
    EXPECT_EQ(e.kind, net::ErrorKind::ResourceExhausted) << e.what();
    EXPECT_NE(std::string(e.what()).find("this client"), std::string::npos) << e.what();
  }
  EXPECT_EQ(submitAs(alice, "a1").request_id(), "a1");  // a retry of a job it has is no new place
  submitAs(bob, "b1");  // the others still get in
  farm.coordinator.jobs().cancel(submitAs(alice, "a2").job_id());
  submitAs(alice, "a3");  // a place given back is taken again
  submitAs(server::Access::all(), "admin-1");  // an administrator is not counted per client
  EXPECT_THROW(submitAs(server::Access::all(), "admin-2"), net::FarmError);  // but the farm's limit (4) holds
}

// R18: the address a failed authentication is counted against, whatever port the peer
// used, and the lockout's count per address.
TEST(Hardening, R18_FailedAuthenticationsCountPerAddress) {
  EXPECT_EQ(server::peerHost("ipv4:10.0.0.7:51234"), "10.0.0.7");
  EXPECT_EQ(server::peerHost("ipv6:[::1]:5"), "::1");
  EXPECT_EQ(server::peerHost("ipv6:[2001:db8::1]:443"), "2001:db8::1");
  EXPECT_EQ(server::peerHost("unix:/tmp/s"), "unix:/tmp/s");
  server::TokenTable none;
  server::Gatekeeper gate(none, server::AuthLimits{3, 60, 60});
  EXPECT_FALSE(gate.failed("10.0.0.7"));
  EXPECT_FALSE(gate.failed("10.0.0.7"));
  EXPECT_FALSE(gate.failed("10.0.0.8"));  // another address has a count of its own
  EXPECT_EQ(gate.lockedFor("10.0.0.7"), 0);
  EXPECT_TRUE(gate.failed("10.0.0.7"));
  EXPECT_GT(gate.lockedFor("10.0.0.7"), 59);
  EXPECT_EQ(gate.lockedFor("10.0.0.8"), 0);
  server::Gatekeeper open(none, server::AuthLimits{0, 60, 60});
  for (int i = 0; i < 100; ++i) EXPECT_FALSE(open.failed("10.0.0.7"));
}

// R27: the health service answered SERVING whatever happened, even with the store held
// busy (a long transaction, a wedged disk). It follows the store now.
TEST(Hardening, R27_HealthIsNotServingWhileTheStoreIsHeldBusy) {
  TempDir dir("cpvs_r27");
  InProcessFarm farm(dir / "data");
  const net::Connection c{farm.server.address(), "", ""};
  EXPECT_EQ(net::healthOf(c), "SERVING");
  EXPECT_EQ(net::healthOf(c, server::kLeasesHealth), "SERVING");
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir / "data/farm.sqlite").c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr), SQLITE_OK);  // holds the write lock
  auto waitFor = [&](const std::string& service, const std::string& want, int seconds) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(seconds);
    std::string got;
    while ((got = net::healthOf(c, service)) != want && std::chrono::steady_clock::now() < end)
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    return got;
  };
  EXPECT_EQ(waitFor("", "NOT_SERVING", 10), "NOT_SERVING");
  // The reaper's rounds fail against the held store: after 10 s leases count as stuck.
  EXPECT_EQ(waitFor(server::kLeasesHealth, "NOT_SERVING", 20), "NOT_SERVING");
  sqlite3_exec(db, "ROLLBACK", nullptr, nullptr, nullptr);
  sqlite3_close(db);
  EXPECT_EQ(waitFor("", "SERVING", 10), "SERVING");
  EXPECT_EQ(waitFor(server::kLeasesHealth, "SERVING", 10), "SERVING");
}

int64_t epochMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

void sqlExec(sqlite3* db, const std::string& sql) {
  char* err = nullptr;
  ASSERT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err), SQLITE_OK) << (err ? err : "") << " in " << sql;
}

/// `count` cancelled jobs with 256-character request ids and long errors in the store at
/// `path`, copied from one record in one transaction: what years of use leave, in a second.
void fillFinishedJobs(const std::string& path, int count) {
  {
    server::FarmStore store(path);
    server::JobRecord j = oneTileJob("j000000");
    j.requestId = std::string(256, 'r');
    store.createJob(j);
    store.setJobState(j.id, server::JobState::Cancelled, std::string(2000, 'e'), epochMs());
  }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlExec(db, "BEGIN; CREATE TEMP TABLE proto AS SELECT * FROM jobs");
  for (int i = 1; i < count; ++i)
    sqlExec(db, "UPDATE proto SET id = printf('j%06d', " + std::to_string(i) + "), request_id = printf('%06d', " +
                    std::to_string(i) + ") || substr(request_id, 7), created_ms = created_ms + 1; "
                    "INSERT INTO jobs SELECT * FROM proto");
  sqlExec(db, "COMMIT");
  sqlite3_close(db);
}

// R16: ListJobs answered every job in one reply, so a few thousand finished jobs passed the
// message limit and `cpvs jobs --all` stopped working. It answers pages now, bounded in
// jobs and in bytes, and the client walks them.
TEST(Hardening, R16_ThousandsOfJobsAreListedPageByPage) {
  TempDir dir("cpvs_r16_pages");
  fs::create_directories(dir / "data");
  fillFinishedJobs(dir / "data/farm.sqlite", 3000);
  InProcessFarm farm(dir / "data");
  auto stub = pb::Farm::NewStub(net::makeChannel(farm.connection()));
  auto page = [&](uint32_t size, const std::string& token, pb::ListJobsReply* reply) {
    grpc::ClientContext ctx;
    pb::ListJobsRequest req;
    req.set_include_finished(true);
    req.set_page_size(size);
    req.set_page_token(token);
    return stub->ListJobs(&ctx, req, reply);
  };
  pb::ListJobsReply first, big, bad;
  ASSERT_TRUE(page(0, "", &first).ok());
  EXPECT_EQ(first.jobs_size(), 100);  // the default page
  EXPECT_FALSE(first.next_page_token().empty());
  ASSERT_TRUE(page(100000, "", &big).ok());
  EXPECT_LE(big.ByteSizeLong(), server::kListReplyBytes + 256);  // bounded in bytes before the 1000 jobs
  EXPECT_GT(big.jobs_size(), 100);
  EXPECT_LT(big.jobs_size(), 1000);
  std::vector<std::string> ids;
  std::string token;
  int pages = 0;
  do {
    pb::ListJobsReply reply;
    ASSERT_TRUE(page(1000, token, &reply).ok());
    for (const auto& j : reply.jobs()) ids.push_back(j.job_id());
    token = reply.next_page_token();
    ASSERT_LT(++pages, 100);
  } while (!token.empty());
  ASSERT_EQ(ids.size(), 3000u);  // every job once, oldest first
  EXPECT_TRUE(std::is_sorted(ids.begin(), ids.end()));
  EXPECT_EQ(std::set<std::string>(ids.begin(), ids.end()).size(), ids.size());
  EXPECT_EQ(farm.client.list(true).size(), 3000u);
  EXPECT_TRUE(farm.client.list(false).empty());
  for (const char* wrong : {"not-a-token", "12:../etc", ":j1", "99999999999999999999999:j1"})
    EXPECT_EQ(page(10, wrong, &bad).error_code(), grpc::StatusCode::INVALID_ARGUMENT) << wrong;
}

// R16, R25: jobs, their artifacts and tile results, scenes and uploads abandoned half-way
// were never forgotten. A finished job goes after its retention (unless a track still
// serves it), a scene no job names after as long unused, an upload after its expiry, and
// files a crash left without a job at start.
TEST(Hardening, R16_R25_FinishedJobsAndAbandonedUploadsAreForgottenInTime) {
  TempDir dir("cpvs_r16_retention");
  const fs::path data = dir / "data";
  for (const char* sub : {"artifacts", "scenes", "tiles/jold"}) fs::create_directories(data / sub);
  const int64_t now = epochMs(), twoHoursAgo = now - 2 * 3600 * 1000;
  const std::string oldUpload(32, 'a'), newUpload(32, 'f');
  const std::string unusedScene(32, 'd'), usedScene(32, 'b'), freshScene(32, 'e');
  {
    server::FarmStore store(data / "farm.sqlite");
    for (const char* id : {"jold", "jnew", "jrun", "jtrack"}) store.createJob(oneTileJob(id));
    store.setJobState("jold", server::JobState::Done, "", twoHoursAgo);
    store.setJobState("jnew", server::JobState::Failed, "failed", now);
    store.setJobState("jrun", server::JobState::Running, "", twoHoursAgo);
    store.setJobState("jtrack", server::JobState::Done, "", twoHoursAgo);
    for (const std::string& hash : {oldUpload, newUpload}) store.putScene({hash, "s.obj", "", 1000, 8, 0, false, ""});
    // Stored scenes: one no job names, one a running job names (oneTileJob's), one just used.
    for (const std::string& hash : {unusedScene, usedScene, freshScene}) store.putScene({hash, "s.obj", "", 2, 2, 1, true, ""});
  }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((data / "farm.sqlite").c_str(), &db), SQLITE_OK);
  sqlExec(db, "INSERT INTO versions(track_id, sequence, job_id) VALUES('t1', 1, 'jtrack')");  // a track still serves it
  sqlExec(db, "UPDATE scenes SET last_used_ms = 0 WHERE hash IN ('" + unusedScene + "', '" + usedScene + "')");
  sqlite3_close(db);
  for (const std::string& hash : {unusedScene, usedScene, freshScene})
    for (const char* ext : {".obj", ".mesh"}) writeFileAtomic(data / "scenes" / (hash + ext), {'v'});
  for (const char* id : {"jold", "jnew", "jtrack", "jgone"}) writeFileAtomic(data / "artifacts" / (std::string(id) + ".cpvs"), {1, 2});
  writeFileAtomic(data / "tiles/jold/0.cpvt", {1});
  for (const std::string& hash : {oldUpload, newUpload}) writeFileAtomic(data / "scenes" / (hash + ".part"), {'v', ' '});
  fs::last_write_time(data / "scenes" / (oldUpload + ".part"), fs::file_time_type::clock::now() - std::chrono::hours(25));

  server::CoordinatorConfig config;
  config.dataDir = data;
  config.retention.keepFinishedSeconds = 3600;
  config.retention.uploadExpirySeconds = 86400;
  {
    InProcessFarm farm(config);
    std::set<std::string> listed;
    for (const auto& j : farm.client.list(true)) listed.insert(j.jobId);
    EXPECT_EQ(listed, (std::set<std::string>{"jnew", "jrun", "jtrack"}));
    EXPECT_THROW(farm.coordinator.jobs().status("jold"), net::FarmError);
    EXPECT_FALSE(fs::exists(data / "artifacts/jold.cpvs"));
    EXPECT_FALSE(fs::exists(data / "tiles/jold"));
    EXPECT_FALSE(fs::exists(data / "artifacts/jgone.cpvs"));  // no job: a prune cut short
    EXPECT_TRUE(fs::exists(data / "artifacts/jnew.cpvs"));
    EXPECT_TRUE(fs::exists(data / "artifacts/jtrack.cpvs"));
    EXPECT_FALSE(farm.coordinator.scenes().uploadStatus(oldUpload).known());
    EXPECT_FALSE(fs::exists(data / "scenes" / (oldUpload + ".part")));
    EXPECT_EQ(farm.coordinator.scenes().uploadStatus(newUpload).received(), 8u);
    EXPECT_FALSE(farm.coordinator.scenes().uploadStatus(unusedScene).known());
    EXPECT_FALSE(fs::exists(data / "scenes" / (unusedScene + ".obj")));
    EXPECT_FALSE(fs::exists(data / "scenes" / (unusedScene + ".mesh")));
    for (const std::string& kept : {usedScene, freshScene}) {
      EXPECT_TRUE(farm.coordinator.scenes().uploadStatus(kept).complete()) << kept;
      EXPECT_TRUE(fs::exists(data / "scenes" / (kept + ".mesh"))) << kept;
    }
  }
  // While it runs: a job that ends is forgotten once its retention has passed.
  config.retention.keepFinishedSeconds = 2;
  config.retention.intervalSeconds = 0.2;
  InProcessFarm farm(config);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(15);
  while (fs::exists(data / "artifacts/jnew.cpvs") && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_FALSE(fs::exists(data / "artifacts/jnew.cpvs"));
  std::set<std::string> listed;
  for (const auto& j : farm.client.list(true)) listed.insert(j.jobId);
  EXPECT_EQ(listed, (std::set<std::string>{"jrun", "jtrack"}));
}

}  // namespace
}  // namespace cpvs
