// Findings of the reliability review (../shared/notes/reliability-review.md), each
// reproduced by the test named after it before it was fixed.
#include <gtest/gtest.h>
#include <grpcpp/grpcpp.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "coordinator/coordinator.h"
#include "cpvs/base/file.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/text.h"
#include "cpvs/client/farm_client.h"
#include "cpvs/net/channel.h"
#include "cpvs/net/convert.h"
#include "cpvs/scene/obj_writer.h"
#include "cpvs/scene/source.h"
#include "cpvs/v1/farm.grpc.pb.h"
#include "rpc/farm_server.h"
#include "store/farm_store.h"

namespace cpvs {
namespace {

namespace fs = std::filesystem;
namespace pb = ::cpvs::v1;

class TempDir {
 public:
  explicit TempDir(const std::string& name)
      : path_(fs::temp_directory_path() / (name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

server::JobRecord oneTileJob(const std::string& id) {
  server::JobRecord j;
  j.id = id;
  j.requestId = "req-" + id;
  j.sceneHash = std::string(32, 'b');
  j.geometryHash = std::string(32, 'c');
  j.createdMs = 1000;
  j.tilesPerSide = 1;
  j.tilesTotal = 1;
  j.resolution = 64;
  j.grid.frame = LightFrame::fromDirection({0, -1, 0});
  j.grid.log2Resolution = 6;
  return j;
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
  const std::string obj = dir / "box.obj";
  writeObj(obj, openScene("city:1:1"));
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  server::Coordinator coordinator(config);
  server::TokenTable open;
  server::FarmServer farm(coordinator, open, "127.0.0.1:0");
  const net::Connection c{farm.address(), "", ""};
  client::FarmClient farmClient(c);
  pb::BakeSpec spec;
  spec.set_scene_hash(farmClient.uploadScene(obj).sceneHash);
  *spec.mutable_sun_direction() = net::toProto(Vec3{0.2, -1, 0.1});
  spec.set_resolution("64");
  const pb::JobStatus job = farmClient.submit("r8", spec);

  auto workers = pb::Workers::NewStub(net::makeChannel(c));
  for (int attempt = 0; attempt < 3; ++attempt) {
    pb::LeaseRequest lr;
    lr.set_worker_id("w");
    pb::TileLease lease;
    grpc::ClientContext lctx;
    ASSERT_TRUE(workers->LeaseTile(&lctx, lr, &lease).ok());
    ASSERT_TRUE(lease.granted());
    pb::FailRequest fr;
    fr.set_lease_id(lease.lease_id());
    fr.set_reason(std::string(999, 'x') + "\xC3\xA9 and more");  // é across byte 1000
    pb::FailReply reply;
    grpc::ClientContext fctx;
    ASSERT_TRUE(workers->FailTile(&fctx, fr, &reply).ok());
  }
  const std::vector<pb::JobStatus> jobs = farmClient.list(true);  // parses: the error is UTF-8
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].state(), pb::JOB_FAILED);
  EXPECT_NE(jobs[0].error().find("failed 3 times"), std::string::npos);
}

// R15 (and R1's server part): CompleteTile under a lease nobody holds is refused at the
// first chunk, not after the whole announced stream.
TEST(Hardening, R15_AResultUnderAnUnknownLeaseIsRefusedAtItsFirstChunk) {
  TempDir dir("cpvs_r15");
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  server::Coordinator coordinator(config);
  server::TokenTable open;
  server::FarmServer farm(coordinator, open, "127.0.0.1:0");
  auto workers = pb::Workers::NewStub(net::makeChannel(net::Connection{farm.address(), "", ""}));
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
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  {
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
  server::Coordinator coordinator(config);
  EXPECT_EQ(coordinator.scenes().uploadStatus(hash).received(), 100u);
  server::TokenTable open;
  server::FarmServer farm(coordinator, open, "127.0.0.1:0");
  client::FarmClient farmClient(net::Connection{farm.address(), "", ""});
  const client::FarmClient::UploadResult up = farmClient.uploadScene(obj);
  EXPECT_EQ(up.resumedFrom, 100u);
  EXPECT_TRUE(coordinator.scenes().uploadStatus(hash).complete());
}

}  // namespace
}  // namespace cpvs

namespace cpvs {
namespace {

// R2: tile_size 8 at 256K asked the store for 2^30 tile rows in one transaction.
TEST(Hardening, R2_AJobOfTooManyTilesIsRefusedAtOnce) {
  TempDir dir("cpvs_r2");
  const std::string obj = dir / "box.obj";
  writeObj(obj, openScene("city:1:1"));
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  server::Coordinator coordinator(config);
  server::TokenTable open;
  server::FarmServer farm(coordinator, open, "127.0.0.1:0");
  client::FarmClient farmClient(net::Connection{farm.address(), "", ""});
  pb::BakeSpec spec;
  spec.set_scene_hash(farmClient.uploadScene(obj).sceneHash);
  *spec.mutable_sun_direction() = net::toProto(Vec3{0.2, -1, 0.1});
  spec.set_resolution("256K");
  spec.mutable_options()->set_tile_size(8);
  const auto start = std::chrono::steady_clock::now();
  try {
    farmClient.submit("r2", spec);
    ADD_FAILURE() << "a job of 2^30 tiles was accepted";
  } catch (const client::FarmCallError& e) {
    EXPECT_EQ(e.kind(), net::ErrorKind::InvalidArgument);
    EXPECT_NE(std::string(e.what()).find("tiles of at least 1024 texels"), std::string::npos) << e.what();
  }
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(2));
  EXPECT_TRUE(farmClient.list(true).empty());
}

// R14: a second coordinator on the same data folder, or on the same port, is refused.
TEST(Hardening, R14_OneCoordinatorPerDataFolderAndPerPort) {
  TempDir dir("cpvs_r14");
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  server::Coordinator first(config);
  try {
    server::Coordinator second(config);
    ADD_FAILURE() << "two coordinators opened one data folder";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("in use by another cpvs-server"), std::string::npos) << e.what();
  }
  server::TokenTable open;
  server::FarmServer one(first, open, "127.0.0.1:0");
  server::CoordinatorConfig other;
  other.dataDir = dir / "other";
  server::Coordinator otherCoordinator(other);
  EXPECT_THROW(server::FarmServer(otherCoordinator, open, one.address()), InputError);
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

}  // namespace
}  // namespace cpvs

#include "tile_worker.h"

namespace cpvs {
namespace {

// R16: worker-supplied stage names became stored rows without bound; only the pipeline's
// stages are taken now.
TEST(Hardening, R16_AResultWithAStageThePipelineDoesNotHaveIsRefused) {
  TempDir dir("cpvs_r16");
  const std::string obj = dir / "box.obj";
  writeObj(obj, openScene("city:1:1"));
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  server::Coordinator coordinator(config);
  server::TokenTable open;
  server::FarmServer farm(coordinator, open, "127.0.0.1:0");
  const net::Connection c{farm.address(), "", ""};
  client::FarmClient farmClient(c);
  pb::BakeSpec spec;
  spec.set_scene_hash(farmClient.uploadScene(obj).sceneHash);
  *spec.mutable_sun_direction() = net::toProto(Vec3{0.2, -1, 0.1});
  spec.set_resolution("64");
  farmClient.submit("r16", spec);
  auto workers = pb::Workers::NewStub(net::makeChannel(c));
  pb::LeaseRequest lr;
  lr.set_worker_id("w");
  pb::TileLease lease;
  grpc::ClientContext lctx;
  ASSERT_TRUE(workers->LeaseTile(&lctx, lr, &lease).ok());
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
  const std::string obj = dir / "box.obj";
  writeObj(obj, openScene("city:1:1"));
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  server::Coordinator coordinator(config);
  server::TokenTable open;
  server::FarmServer farm(coordinator, open, "127.0.0.1:0");
  const net::Connection c{farm.address(), "", ""};
  worker::WorkerConfig wc;
  wc.server = c;
  wc.cacheDir = dir / "cache";
  fs::create_directories(wc.cacheDir);
  wc.workerId = "w";
  worker::TileWorker tileWorker(wc);
  std::thread workerThread([&] { tileWorker.run(); });
  client::FarmClient farmClient(c);
  pb::BakeSpec spec;
  spec.set_scene_hash(farmClient.uploadScene(obj).sceneHash);
  *spec.mutable_sun_direction() = net::toProto(Vec3{0.2, -1, 0.1});
  spec.set_resolution("64");
  const pb::JobStatus job = farmClient.watch(farmClient.submit("r21", spec).job_id());
  tileWorker.stop();
  workerThread.join();
  ASSERT_EQ(job.state(), pb::JOB_DONE);
  fs::remove(coordinator.jobs().artifactPath(job.job_id(), nullptr));
  try {
    farmClient.download(job.job_id(), dir / "out.cpvs");
    ADD_FAILURE() << "downloaded a missing artifact";
  } catch (const client::FarmCallError& e) {
    EXPECT_EQ(e.kind(), net::ErrorKind::DataLoss) << e.what();
    EXPECT_EQ(std::string(e.what()).find(dir / "data"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace cpvs

#include <sqlite3.h>

namespace cpvs {
namespace {

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
  const std::string obj = dir / "box.obj";
  writeObj(obj, openScene("city:1:1"));
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  std::string jobId;
  {
    server::Coordinator coordinator(config);
    server::TokenTable open;
    server::FarmServer farm(coordinator, open, "127.0.0.1:0");
    client::FarmClient farmClient(net::Connection{farm.address(), "", ""});
    pb::BakeSpec spec;
    spec.set_scene_hash(farmClient.uploadScene(obj).sceneHash);
    *spec.mutable_sun_direction() = net::toProto(Vec3{0.2, -1, 0.1});
    spec.set_resolution("64");
    spec.mutable_options()->set_tile_size(32);  // 4 tiles
    jobId = farmClient.submit("r4", spec).job_id();
  }
  {
    // Tile 0 acknowledged, but its file lost (as after a power cut before R3's syncs).
    server::FarmStore store(dir / "data/farm.sqlite");
    ASSERT_TRUE(store.leaseNextTile("w", "l-lost", 1000, 1e15).has_value());
    ASSERT_TRUE(store.completeTile(jobId, 0));
  }
  server::Coordinator coordinator(config);
  server::TokenTable open;
  server::FarmServer farm(coordinator, open, "127.0.0.1:0");
  const net::Connection c{farm.address(), "", ""};
  worker::WorkerConfig wc;
  wc.server = c;
  wc.cacheDir = dir / "cache";
  fs::create_directories(wc.cacheDir);
  wc.workerId = "w";
  worker::TileWorker tileWorker(wc);
  std::thread workerThread([&] { tileWorker.run(); });
  client::FarmClient farmClient(c);
  const pb::JobStatus done = farmClient.watch(jobId);
  tileWorker.stop();
  workerThread.join();
  EXPECT_EQ(done.state(), pb::JOB_DONE) << done.error();
  EXPECT_EQ(done.tiles_done(), 4u);
}

}  // namespace
}  // namespace cpvs

#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <mutex>
#include <sstream>

#include "cpvs/base/text.h"

namespace cpvs {
namespace {

// R26: worker ids and failure reasons went into the log raw: a newline forged log lines.
TEST(Hardening, R26_WorkerTextCannotForgeLogLines) {
  EXPECT_EQ(loggable("a\nb\x1b[31m"), "a\\x0Ab\\x1B[31m");
  TempDir dir("cpvs_r26");
  const std::string obj = dir / "box.obj";
  writeObj(obj, openScene("city:1:1"));
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  server::Coordinator coordinator(config);
  server::TokenTable open;
  server::FarmServer farm(coordinator, open, "127.0.0.1:0");
  client::FarmClient farmClient(net::Connection{farm.address(), "", ""});
  pb::BakeSpec spec;
  spec.set_scene_hash(farmClient.uploadScene(obj).sceneHash);
  *spec.mutable_sun_direction() = net::toProto(Vec3{0.2, -1, 0.1});
  spec.set_resolution("64");
  farmClient.submit("r26", spec);

  std::ostringstream log;
  auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(log);
  spdlog::default_logger()->sinks().push_back(sink);
  const pb::TileLease lease = coordinator.leases().lease("w\n[2026-01-01 00:00:00.000] [info] job jX done");
  ASSERT_TRUE(lease.granted());
  coordinator.leases().failTile(lease.lease_id(), "bad\n[2026-01-01 00:00:00.000] [info] all good");
  spdlog::default_logger()->sinks().pop_back();
  std::istringstream lines(log.str());
  std::string line;
  int warnings = 0;
  while (std::getline(lines, line)) {
    EXPECT_NE(line.rfind("[2026-01-01", 0), 0u) << "a forged line: " << line;
    warnings += line.find("failed on w\\x0A[2026-01-01") != std::string::npos;
  }
  EXPECT_EQ(warnings, 1) << log.str();
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
    *out->mutable_grid() = net::toProto(g);
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
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&service);
  auto server = builder.BuildAndStart();
  ASSERT_TRUE(server);
  const std::string cache = dir / "a/b/cache";
  fs::create_directories(cache);
  worker::WorkerConfig wc;
  wc.server = net::Connection{"127.0.0.1:" + std::to_string(port), "", ""};
  wc.cacheDir = cache;
  wc.workerId = "w";
  wc.maxTiles = 1;
  worker::TileWorker tileWorker(wc);
  tileWorker.run();  // returns after its one tile
  server->Shutdown();
  EXPECT_FALSE(fs::exists(dir / "a/escaped.part"));
  EXPECT_FALSE(fs::exists(dir / "a/escaped"));
  ASSERT_EQ(service.reasons.size(), 1u);
  EXPECT_NE(service.reasons[0].find("scene_hash"), std::string::npos) << service.reasons[0];
}

}  // namespace
}  // namespace cpvs

namespace cpvs {
namespace {

// R12: a hung bake renewed its lease forever; renewals now stop after --max-tile-seconds.
TEST(Hardening, R12_RenewalsEndAfterTheLongestATileMayTake) {
  TempDir dir("cpvs_r12");
  const std::string obj = dir / "box.obj";
  writeObj(obj, openScene("city:1:1"));
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  config.leaseSeconds = 1;
  config.maxTileSeconds = 2;
  config.maxAttempts = 5;
  server::Coordinator coordinator(config);
  server::TokenTable open;
  server::FarmServer farm(coordinator, open, "127.0.0.1:0");
  client::FarmClient farmClient(net::Connection{farm.address(), "", ""});
  pb::BakeSpec spec;
  spec.set_scene_hash(farmClient.uploadScene(obj).sceneHash);
  *spec.mutable_sun_direction() = net::toProto(Vec3{0.2, -1, 0.1});
  spec.set_resolution("64");
  farmClient.submit("r12", spec);
  const pb::TileLease first = coordinator.leases().lease("hung");
  ASSERT_TRUE(first.granted());
  const auto start = std::chrono::steady_clock::now();
  bool stillValid = true;
  while (stillValid && std::chrono::steady_clock::now() - start < std::chrono::seconds(5)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    stillValid = coordinator.leases().renew(first.lease_id()).valid();
  }
  const double refusedAfter = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_FALSE(stillValid);
  EXPECT_GT(refusedAfter, 1.5);  // renewals past the lease's own length were honoured...
  EXPECT_LT(refusedAfter, 3.0);  // ...until the tile's 2 s were up
  // The reaper returns the tile; another worker gets it.
  pb::TileLease second;
  while (!second.granted() && std::chrono::steady_clock::now() - start < std::chrono::seconds(8)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    second = coordinator.leases().lease("healthy");
  }
  EXPECT_TRUE(second.granted());
  EXPECT_EQ(second.tile_index(), first.tile_index());
}

}  // namespace
}  // namespace cpvs

namespace cpvs {
namespace {

// Between a worker and the coordinator: forwards every call, but answers the first
// CompleteTile with UNAVAILABLE, as a coordinator that restarts under it would.
class FlakyOnce final : public pb::Workers::Service {
 public:
  explicit FlakyOnce(const std::string& address) : stub_(pb::Workers::NewStub(net::makeChannel({address, "", ""}))) {}
  grpc::Status LeaseTile(grpc::ServerContext*, const pb::LeaseRequest* req, pb::TileLease* out) override {
    grpc::ClientContext ctx;
    return stub_->LeaseTile(&ctx, *req, out);
  }
  grpc::Status RenewLease(grpc::ServerContext*, const pb::RenewRequest* req, pb::RenewReply* out) override {
    grpc::ClientContext ctx;
    return stub_->RenewLease(&ctx, *req, out);
  }
  grpc::Status FailTile(grpc::ServerContext*, const pb::FailRequest* req, pb::FailReply* out) override {
    grpc::ClientContext ctx;
    return stub_->FailTile(&ctx, *req, out);
  }
  grpc::Status FetchScene(grpc::ServerContext*, const pb::FetchSceneRequest* req,
                          grpc::ServerWriter<pb::SceneChunk>* writer) override {
    grpc::ClientContext ctx;
    auto reader = stub_->FetchScene(&ctx, *req);
    pb::SceneChunk chunk;
    while (reader->Read(&chunk)) writer->Write(chunk);
    return reader->Finish();
  }
  grpc::Status CompleteTile(grpc::ServerContext*, grpc::ServerReader<pb::TileResultChunk>* reader,
                            pb::CompleteReply* out) override {
    std::vector<pb::TileResultChunk> chunks;
    pb::TileResultChunk chunk;
    while (reader->Read(&chunk)) chunks.push_back(chunk);
    if (completes++ == 0) return grpc::Status(grpc::StatusCode::UNAVAILABLE, "restarting");
    grpc::ClientContext ctx;
    auto writer = stub_->CompleteTile(&ctx, out);
    for (const auto& c : chunks) writer->Write(c);
    writer->WritesDone();
    return writer->Finish();
  }
  std::atomic<int> completes{0};

 private:
  std::unique_ptr<pb::Workers::Stub> stub_;
};

// R17: a worker whose CompleteTile met UNAVAILABLE threw its baked tile away (the tile was
// baked again after its lease expired); now it sends it again.
TEST(Hardening, R17_ABakedTileIsSentAgainNotBakedAgain) {
  TempDir dir("cpvs_r17");
  const std::string obj = dir / "box.obj";
  writeObj(obj, openScene("city:1:1"));
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  server::Coordinator coordinator(config);
  server::TokenTable open;
  server::FarmServer farm(coordinator, open, "127.0.0.1:0");
  FlakyOnce proxy(farm.address());
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&proxy);
  auto proxyServer = builder.BuildAndStart();
  ASSERT_TRUE(proxyServer);

  client::FarmClient farmClient(net::Connection{farm.address(), "", ""});
  pb::BakeSpec spec;
  spec.set_scene_hash(farmClient.uploadScene(obj).sceneHash);
  *spec.mutable_sun_direction() = net::toProto(Vec3{0.2, -1, 0.1});
  spec.set_resolution("64");
  const std::string jobId = farmClient.submit("r17", spec).job_id();

  std::ostringstream log;
  auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(log);
  spdlog::default_logger()->sinks().push_back(sink);
  worker::WorkerConfig wc;
  wc.server = net::Connection{"127.0.0.1:" + std::to_string(port), "", ""};
  wc.cacheDir = dir / "cache";
  fs::create_directories(wc.cacheDir);
  wc.workerId = "w";
  wc.maxTiles = 1;
  worker::TileWorker tileWorker(wc);
  tileWorker.run();  // one tile, delivered on the second try
  spdlog::default_logger()->sinks().pop_back();
  proxyServer->Shutdown();

  EXPECT_EQ(proxy.completes.load(), 2);
  ASSERT_EQ(tileWorker.tilesDone(), 1u);  // before the watch, which would wait for the tile
  const pb::JobStatus done = farmClient.watch(jobId);
  EXPECT_EQ(done.state(), pb::JOB_DONE) << done.error();
  size_t bakes = 0;
  for (size_t at = log.str().find(": baking"); at != std::string::npos; at = log.str().find(": baking", at + 1)) ++bakes;
  EXPECT_EQ(bakes, 1u) << log.str();
}

}  // namespace
}  // namespace cpvs

namespace cpvs {
namespace {

// Forwards to the coordinator, but shows the worker a deadline five minutes later than
// the coordinator's (a worker clock five minutes behind), and counts renewals.
class SkewedClock final : public pb::Workers::Service {
 public:
  SkewedClock(const std::string& address, bool sendLength)
      : stub_(pb::Workers::NewStub(net::makeChannel({address, "", ""}))), sendLength_(sendLength) {}
  grpc::Status LeaseTile(grpc::ServerContext*, const pb::LeaseRequest* req, pb::TileLease* out) override {
    grpc::ClientContext ctx;
    grpc::Status s = stub_->LeaseTile(&ctx, *req, out);
    out->set_deadline_unix_ms(out->deadline_unix_ms() + 300000);
    if (!sendLength_) out->clear_lease_ms();
    return s;
  }
  grpc::Status RenewLease(grpc::ServerContext*, const pb::RenewRequest* req, pb::RenewReply* out) override {
    ++renewals;
    grpc::ClientContext ctx;
    grpc::Status s = stub_->RenewLease(&ctx, *req, out);
    out->set_deadline_unix_ms(out->deadline_unix_ms() + 300000);
    if (!sendLength_) out->clear_lease_ms();
    return s;
  }
  grpc::Status FailTile(grpc::ServerContext*, const pb::FailRequest* req, pb::FailReply* out) override {
    grpc::ClientContext ctx;
    return stub_->FailTile(&ctx, *req, out);
  }
  grpc::Status FetchScene(grpc::ServerContext*, const pb::FetchSceneRequest* req,
                          grpc::ServerWriter<pb::SceneChunk>* writer) override {
    grpc::ClientContext ctx;
    auto reader = stub_->FetchScene(&ctx, *req);
    pb::SceneChunk chunk;
    while (reader->Read(&chunk)) writer->Write(chunk);
    return reader->Finish();
  }
  grpc::Status CompleteTile(grpc::ServerContext*, grpc::ServerReader<pb::TileResultChunk>* reader,
                            pb::CompleteReply* out) override {
    grpc::ClientContext ctx;
    auto writer = stub_->CompleteTile(&ctx, out);
    pb::TileResultChunk chunk;
    while (reader->Read(&chunk)) writer->Write(chunk);
    writer->WritesDone();
    return writer->Finish();
  }
  std::atomic<int> renewals{0};

 private:
  std::unique_ptr<pb::Workers::Stub> stub_;
  bool sendLength_;
};

// R11: the worker's renewal period came from the coordinator's wall-clock deadline minus
// its own clock; five minutes of skew meant no renewal within a 0.3 s lease.
TEST(Hardening, R11_RenewalsFollowTheLeaseLengthWhateverTheClocks) {
  TempDir dir("cpvs_r11");
  const std::string obj = dir / "city.obj";
  writeObj(obj, openScene("city:3:2"));
  server::CoordinatorConfig config;
  config.dataDir = dir / "data";
  config.leaseSeconds = 0.3;  // renewals every 0.1 s
  server::Coordinator coordinator(config);
  server::TokenTable open;
  server::FarmServer farm(coordinator, open, "127.0.0.1:0");
  client::FarmClient farmClient(net::Connection{farm.address(), "", ""});
  pb::BakeSpec spec;
  spec.set_scene_hash(farmClient.uploadScene(obj).sceneHash);
  *spec.mutable_sun_direction() = net::toProto(Vec3{0.2, -1, 0.1});
  spec.set_resolution("4096");  // one tile that bakes for a second or more
  spec.mutable_options()->set_tile_size(4096);
  farmClient.submit("r11", spec);

  SkewedClock proxy(farm.address(), true);
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&proxy);
  auto proxyServer = builder.BuildAndStart();
  worker::WorkerConfig wc;
  wc.server = net::Connection{"127.0.0.1:" + std::to_string(port), "", ""};
  wc.cacheDir = dir / "cache";
  fs::create_directories(wc.cacheDir);
  wc.workerId = "w";
  wc.maxTiles = 1;
  const auto start = std::chrono::steady_clock::now();
  worker::TileWorker tileWorker(wc);
  tileWorker.run();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  proxyServer->Shutdown();
  if (seconds < 0.4) GTEST_SKIP() << "the tile baked in " << seconds << " s, too fast to need renewals here";
  EXPECT_GE(proxy.renewals.load(), 2);
  EXPECT_EQ(coordinator.jobs().list(true).at(0).tiles_done(), 1u);  // the lease held to the end
}

}  // namespace
}  // namespace cpvs
