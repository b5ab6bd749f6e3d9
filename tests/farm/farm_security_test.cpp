// The coordinator's edge against broken and hostile callers, through the generated stubs
// with no client or worker program in between: every RPC under every kind of token;
// malformed requests, each with its documented status, after each of which the server
// still serves and its stored scene and jobs are intact; requests raced against each
// other; and the lease rules, with the test acting as a worker. One coordinator process
// per suite, on loopback, port 0.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <set>
#include <thread>

#include "scene_testing.h"
#include "cpvs/scene/boxes.h"
#include "cpvs/scene/import.h"
#include "cpvs/scene/obj_writer.h"
#include "cpvs/bake/bake.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/scene/source.h"
#include "cpvs/io/sub_dag_file.h"
#include "cpvs/v1/farm.grpc.pb.h"
#include "cpvs/net/channel.h"
#include "cpvs/net/status.h"
#include "cpvs/net/convert.h"
#include "process_testing.h"

namespace cpvs {
namespace {

using testing::bakeTileWith;
using testing::bakeWith;

namespace fs = std::filesystem;
namespace pb = ::cpvs::v1;
using grpc::StatusCode;
using testing::ChildProcess;

const std::string kClientToken = "bb34f308bb8754bc42d72ebdd4f9a39a9f0c6d49";
const std::string kWorkerToken = "d09b8cf6586f9f8592c562a99c8627c0120b4013";
const std::string kAdminToken = "b3d6ee7361a489443d75bc0c723658c0cf53cee6";
// Two client tokens of one owner ("team"): they share their jobs, and see no other's.
const std::string kTeamToken = "5e0c7a21f9d84b36a1c2e8f07d93b64a2f1e5c80";
const std::string kTeamMateToken = "a7f3c9e1d2b8406f95e7c3a1b0d4f8e26c9a7b13";
const std::string kWrongToken = "cb8f688657ebc5ee9f342fc9a1d5d709ea024985";  // a token's shape, in no table

/// Every RPC of these tests ends within this many seconds.
constexpr double kRpcSeconds = 10;

std::string codeName(StatusCode code) {
  std::string s = net::describe(grpc::Status(code, ""));
  return s.substr(0, s.find(':'));
}

std::string hashOf(const std::string& bytes) { return contentHash(bytes.data(), bytes.size()).hex(); }

std::string fileText(const fs::path& path) {
  if (!fs::exists(path)) return "";
  std::vector<uint8_t> b = readFile(path.string());
  return std::string(b.begin(), b.end());
}

/// The scene every suite bakes: a slab with a tower and a bridge-like bar over it.
std::string testSceneObj() {
  Scene scene;
  appendBox(scene, {-4, -0.5, -4}, {4, 0, 4});
  appendBox(scene, {-1, 0, -1}, {1, 3, 1});
  appendBox(scene, {-3, 2, 1.5}, {3, 2.5, 2.5});
  return objText(scene, "cpvs farm security test scene");
}

/// The chunks of an upload of bytes [from, to) of a file: the first names the scene.
std::vector<pb::UploadSceneChunk> uploadChunks(const std::string& hash, const std::string& fileName,
                                               const std::string& bytes, size_t from = 0,
                                               size_t to = std::string::npos) {
  to = std::min(to, bytes.size());
  std::vector<pb::UploadSceneChunk> out;
  size_t at = from;
  do {
    pb::UploadSceneChunk c;
    if (out.empty()) {
      c.set_scene_hash(hash);
      c.set_file_name(fileName);
      c.set_total_size(bytes.size());
    }
    size_t n = std::min(net::kChunkBytes, to - at);
    c.set_offset(at);
    c.set_data(bytes.substr(at, n));
    out.push_back(std::move(c));
    at += n;
  } while (at < to);
  return out;
}

/// The chunks of a tile result; the checksum is the data's unless given.
std::vector<pb::TileResultChunk> resultChunks(const std::string& leaseId, const std::string& bytes,
                                              const std::string& checksum = "") {
  std::vector<pb::TileResultChunk> out;
  size_t at = 0;
  do {
    pb::TileResultChunk c;
    if (out.empty()) {
      c.set_lease_id(leaseId);
      c.set_total_size(bytes.size());
      c.set_checksum(checksum.empty() ? hashOf(bytes) : checksum);
      auto* st = c.add_stages();
      st->set_stage("render");
      st->set_seconds(0.01);
    }
    size_t n = std::min(net::kChunkBytes, bytes.size() - at);
    c.set_data(bytes.substr(at, n));
    out.push_back(std::move(c));
    at += n;
  } while (at < bytes.size());
  return out;
}

/// One coordinator process with a tokens file, and stubs of both services on one channel
/// (tokens travel with each call). Every call has a deadline.
class FarmUnderTest {
 public:
  FarmUnderTest(const fs::path& dir, const std::string& name, const std::vector<std::string>& flags)
      : data_(dir / (name + ".data")) {
    std::string addressFile = (dir / (name + ".address")).string();
    std::vector<std::string> argv{CPVS_SERVER, "--listen", "127.0.0.1:0", "--data", data_.string(),
                                  "--address-file", addressFile, "--tokens", (dir / "tokens").string()};
    argv.insert(argv.end(), flags.begin(), flags.end());
    process_ = std::make_unique<ChildProcess>(argv, (dir / (name + ".log")).string());
    address_ = testing::waitForFile(addressFile, 30);
    channel_ = net::makeChannel({address_, "", ""});
    farm_ = pb::Farm::NewStub(channel_);
    workers_ = pb::Workers::NewStub(channel_);
  }

  const std::string& address() const { return address_; }
  const fs::path& dataDir() const { return data_; }
  bool running() { return process_->running(); }
  pid_t pid() const { return process_->pid(); }
  std::string log() const { return process_->log(); }

  void prepare(grpc::ClientContext& ctx, const std::string& token, double seconds = kRpcSeconds) const {
    net::prepare(ctx, net::Connection{address_, token, ""}, seconds);
  }

  // --- Farm ---
  grpc::Status uploadStatus(const std::string& token, const std::string& hash, pb::UploadStatus* out = nullptr) {
    grpc::ClientContext ctx;
    prepare(ctx, token);
    pb::SceneRef req;
    req.set_scene_hash(hash);
    pb::UploadStatus r;
    grpc::Status s = farm_->GetUploadStatus(&ctx, req, &r);
    if (out) *out = r;
    return s;
  }
  grpc::Status upload(const std::string& token, const std::vector<pb::UploadSceneChunk>& chunks,
                      pb::UploadSceneReply* out = nullptr, pb::Farm::Stub* stub = nullptr) {
    grpc::ClientContext ctx;
    prepare(ctx, token);
    pb::UploadSceneReply r;
    auto writer = (stub ? stub : farm_.get())->UploadScene(&ctx, &r);
    for (const auto& c : chunks)
      if (!writer->Write(c)) break;  // the server ended the call; Finish says why
    writer->WritesDone();
    grpc::Status s = writer->Finish();
    if (out) *out = r;
    return s;
  }
  grpc::Status submit(const std::string& token, const pb::SubmitBakeRequest& req, pb::JobStatus* out = nullptr) {
    grpc::ClientContext ctx;
    prepare(ctx, token);
    pb::JobStatus r;
    grpc::Status s = farm_->SubmitBake(&ctx, req, &r);
    if (out) *out = r;
    return s;
  }
  /// Reads the whole watch stream; `last` is its last message.
  grpc::Status watch(const std::string& token, const std::string& jobId, pb::JobStatus* last = nullptr,
                     double seconds = kRpcSeconds) {
    grpc::ClientContext ctx;
    prepare(ctx, token, seconds);
    pb::JobRef req;
    req.set_job_id(jobId);
    auto reader = farm_->WatchJob(&ctx, req);
    pb::JobStatus m;
    while (reader->Read(&m))
      if (last) *last = m;
    return reader->Finish();
  }
  grpc::Status cancel(const std::string& token, const std::string& jobId, pb::JobStatus* out = nullptr) {
    grpc::ClientContext ctx;
    prepare(ctx, token);
    pb::JobRef req;
    req.set_job_id(jobId);
    pb::JobStatus r;
    grpc::Status s = farm_->CancelJob(&ctx, req, &r);
    if (out) *out = r;
    return s;
  }
  grpc::Status list(const std::string& token, bool includeFinished, pb::ListJobsReply* out = nullptr) {
    grpc::ClientContext ctx;
    prepare(ctx, token);
    pb::ListJobsRequest req;
    req.set_include_finished(includeFinished);
    pb::ListJobsReply r;
    grpc::Status s = farm_->ListJobs(&ctx, req, &r);
    if (out) *out = r;
    return s;
  }
  /// The job as listed (with finished ones); an empty status when it is not listed.
  pb::JobStatus job(const std::string& jobId) {
    pb::ListJobsReply all;
    list(kClientToken, true, &all);
    for (const auto& j : all.jobs())
      if (j.job_id() == jobId) return j;
    return {};
  }
  grpc::Status download(const std::string& token, const std::string& jobId, uint64_t offset,
                        std::string* bytes = nullptr, std::string* checksum = nullptr) {
    grpc::ClientContext ctx;
    prepare(ctx, token);
    pb::DownloadRequest req;
    req.set_job_id(jobId);
    req.set_offset(offset);
    auto reader = farm_->DownloadArtifact(&ctx, req);
    pb::ArtifactChunk c;
    while (reader->Read(&c)) {
      if (bytes) *bytes += c.data();
      if (checksum) *checksum = c.checksum();
    }
    return reader->Finish();
  }

  // --- Workers ---
  grpc::Status lease(const std::string& token, const std::string& workerId, pb::TileLease* out = nullptr) {
    grpc::ClientContext ctx;
    prepare(ctx, token);
    pb::LeaseRequest req;
    req.set_worker_id(workerId);
    pb::TileLease r;
    grpc::Status s = workers_->LeaseTile(&ctx, req, &r);
    if (out) *out = r;
    return s;
  }
  grpc::Status renew(const std::string& token, const std::string& leaseId, pb::RenewReply* out = nullptr) {
    grpc::ClientContext ctx;
    prepare(ctx, token);
    pb::RenewRequest req;
    req.set_lease_id(leaseId);
    pb::RenewReply r;
    grpc::Status s = workers_->RenewLease(&ctx, req, &r);
    if (out) *out = r;
    return s;
  }
  grpc::Status fetch(const std::string& token, const std::string& hash, uint64_t offset,
                     std::string* bytes = nullptr) {
    grpc::ClientContext ctx;
    prepare(ctx, token);
    pb::FetchSceneRequest req;
    req.set_scene_hash(hash);
    req.set_offset(offset);
    auto reader = workers_->FetchScene(&ctx, req);
    pb::SceneChunk c;
    while (reader->Read(&c))
      if (bytes) *bytes += c.data();
    return reader->Finish();
  }
  grpc::Status complete(const std::string& token, const std::vector<pb::TileResultChunk>& chunks,
                        pb::CompleteReply* out = nullptr) {
    grpc::ClientContext ctx;
    prepare(ctx, token);
    pb::CompleteReply r;
    auto writer = workers_->CompleteTile(&ctx, &r);
    for (const auto& c : chunks)
      if (!writer->Write(c)) break;
    writer->WritesDone();
    grpc::Status s = writer->Finish();
    if (out) *out = r;
    return s;
  }
  grpc::Status fail(const std::string& token, const std::string& leaseId, const std::string& reason) {
    grpc::ClientContext ctx;
    prepare(ctx, token);
    pb::FailRequest req;
    req.set_lease_id(leaseId);
    req.set_reason(reason);
    pb::FailReply r;
    return workers_->FailTile(&ctx, req, &r);
  }

  /// Polls LeaseTile until a tile is granted; false after `seconds`.
  bool leaseWithin(const std::string& workerId, double seconds, pb::TileLease* out) {
    auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < end) {
      if (lease(kWorkerToken, workerId, out).ok() && out->granted()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return false;
  }

 private:
  fs::path data_;
  std::unique_ptr<ChildProcess> process_;
  std::string address_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<pb::Farm::Stub> farm_;
  std::unique_ptr<pb::Workers::Stub> workers_;
};

/// What a suite shares: a folder with the tokens file and the test scene, one coordinator
/// started with `flags`, and the scene uploaded to it.
struct SuiteState {
  fs::path dir;
  std::string scenePath, sceneBytes, sceneHash;
  std::unique_ptr<FarmUnderTest> farm;
  std::string problem;  // why the suite could not be set up; empty when it could

  SuiteState(const std::string& name, const std::vector<std::string>& flags) {
    dir = fs::temp_directory_path() / ("cpvs_farm_security_test_" + std::to_string(::getpid()) + "_" + name);
    fs::remove_all(dir);
    fs::create_directories(dir);
    std::ofstream(dir / "tokens") << "# the security test's tokens\nclient " << kClientToken << "\nworker "
                                  << kWorkerToken << "\nadmin " << kAdminToken << "\nclient " << kTeamToken
                                  << " team\nclient " << kTeamMateToken << " team\n";
    sceneBytes = testSceneObj();
    scenePath = (dir / "scene.obj").string();
    std::ofstream(scenePath, std::ios::binary) << sceneBytes;
    sceneHash = hashOf(sceneBytes);
    farm = std::make_unique<FarmUnderTest>(dir, name, flags);
    if (farm->address().empty()) {
      problem = "the coordinator did not start:\n" + farm->log();
      return;
    }
    pb::UploadSceneReply reply;
    grpc::Status s = farm->upload(kClientToken, uploadChunks(sceneHash, "scene.obj", sceneBytes), &reply);
    if (!s.ok() || !reply.complete() || reply.triangles() != 36)
      problem = "the scene upload failed: " + net::describe(s) + "\n" + farm->log();
  }
  ~SuiteState() {
    farm.reset();
    fs::remove_all(dir);
  }

  /// A valid request for the test scene: 64^3, tiles of `tileSize` texels (0: one tile).
  pb::SubmitBakeRequest request(const std::string& requestId, uint32_t tileSize = 0, int priority = 0) const {
    pb::SubmitBakeRequest r;
    r.set_request_id(requestId);
    pb::BakeSpec& spec = *r.mutable_spec();
    spec.set_scene_hash(sceneHash);
    spec.mutable_sun_direction()->set_x(0.3);
    spec.mutable_sun_direction()->set_y(-1);
    spec.mutable_sun_direction()->set_z(0.2);
    spec.set_resolution("64");
    spec.mutable_options()->set_tile_size(tileSize);
    spec.set_priority(priority);
    spec.set_name(requestId);
    return r;
  }

  /// The encoded sub-DAG of tile (tileX, tileY) of a lease's grid, baked as a worker does;
  /// with `otherLight`, of a grid of the same size for another light (a valid result, but
  /// not the job's).
  std::string bake(const pb::TileLease& lease, uint64_t tileX, uint64_t tileY, bool otherLight = false) const {
    Scene scene = loadScene(scenePath);
    OrthoGrid grid = orthoGridOf(net::gridSpecOf(lease.grid()), "grid");
    if (otherLight) grid = makeGrid(scene, LightFrame::fromDirection({-0.6, -1, 0.5}), grid.log2Resolution);
    BakeOptions options = net::fromProto(lease.options());
    std::vector<uint8_t> bytes = encodeSubDag(bakeTileWith(scene, grid, tileX, tileY, options));
    return std::string(bytes.begin(), bytes.end());
  }
};

// =======================================================================================
// Tokens and malformed requests, on a coordinator with small limits.

class FarmSecurityTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // The suite fails authentication on purpose dozens of times a minute: no lockout here
    // (FarmAuthLimit tests it).
    s_ = new SuiteState("security", {"--max-resolution", "4K", "--max-upload-mb", "1", "--max-jobs", "3",
                                     "--auth-failure-limit", "0"});
    if (!s_->problem.empty()) return;
    FarmUnderTest& f = *s_->farm;
    // A job that stays queued through every test (4 tiles of 32^2), and one done by a real
    // worker (one tile, leased first for its priority).
    pb::JobStatus stored, done;
    grpc::Status a = f.submit(kClientToken, s_->request(kStoredRequest, 32), &stored);
    grpc::Status b = f.submit(kClientToken, s_->request("done-job", 0, 1000), &done);
    if (!a.ok() || !b.ok()) {
      s_->problem = "submit failed: " + net::describe(a) + " / " + net::describe(b);
      return;
    }
    storedJob_ = stored.job_id();
    doneJob_ = done.job_id();
    ChildProcess worker({CPVS_WORKER, "--server", f.address(), "--token", kWorkerToken, "--cache",
                         (s_->dir / "worker.cache").string(), "--id", "security-worker", "--max-tiles", "1"},
                        (s_->dir / "worker.log").string());
    pb::JobStatus last;
    grpc::Status w = f.watch(kClientToken, doneJob_, &last, 60);
    int exit = worker.wait(30);
    if (!w.ok() || last.state() != pb::JOB_DONE || exit != 0)
      s_->problem = "the worker did not finish the tiny job: " + net::describe(w) + ", state " +
                    net::jobStateName(net::JobState(last.state())) + ", worker exit " + std::to_string(exit) + "\n" + worker.log() +
                    f.log();
  }
  static void TearDownTestSuite() {
    delete s_;
    s_ = nullptr;
  }
  void SetUp() override { ASSERT_TRUE(s_->problem.empty()) << s_->problem; }

  /// The server still serves, and what was stored before is intact: the scene complete,
  /// the stored job listed and neither failed nor cancelled, the done job still done.
  static void expectIntact(const std::string& after) {
    FarmUnderTest& f = *s_->farm;
    ASSERT_TRUE(f.running()) << "after " << after << ": the coordinator exited\n" << f.log();
    pb::ListJobsReply jobs;
    grpc::Status s = f.list(kClientToken, true, &jobs);
    ASSERT_TRUE(s.ok()) << "after " << after << ": ListJobs " << net::describe(s);
    bool stored = false, done = false;
    for (const auto& j : jobs.jobs()) {
      if (j.job_id() == storedJob_)
        stored = j.state() == pb::JOB_QUEUED || j.state() == pb::JOB_RUNNING;
      if (j.job_id() == doneJob_) done = j.state() == pb::JOB_DONE;
    }
    EXPECT_TRUE(stored) << "after " << after << ": the stored job is not listed as queued or running";
    EXPECT_TRUE(done) << "after " << after << ": the done job is not listed as done";
    pb::UploadStatus st;
    s = f.uploadStatus(kClientToken, s_->sceneHash, &st);
    EXPECT_TRUE(s.ok() && st.complete() && st.received() == s_->sceneBytes.size())
        << "after " << after << ": the stored scene is no longer complete: " << net::describe(s);
  }

  static constexpr const char* kStoredRequest = "stored-job";
  static SuiteState* s_;
  static std::string storedJob_, doneJob_;
};
SuiteState* FarmSecurityTest::s_ = nullptr;
std::string FarmSecurityTest::storedJob_, FarmSecurityTest::doneJob_;

TEST_F(FarmSecurityTest, EveryRpcUnderEveryToken) {
  FarmUnderTest& f = *s_->farm;
  enum class Needs { Client, Worker };
  struct Rpc {
    const char* name;
    Needs needs;
    std::function<grpc::Status(const std::string& token)> call;
  };
  // Requests that change nothing whoever sends them: unknown ids, empty streams, reads.
  const std::vector<Rpc> rpcs = {
      {"GetUploadStatus", Needs::Client, [&](const std::string& t) { return f.uploadStatus(t, s_->sceneHash); }},
      {"UploadScene", Needs::Client, [&](const std::string& t) { return f.upload(t, {}); }},
      {"SubmitBake", Needs::Client, [&](const std::string& t) { return f.submit(t, pb::SubmitBakeRequest()); }},
      {"WatchJob", Needs::Client, [&](const std::string& t) { return f.watch(t, "no-such-job"); }},
      {"CancelJob", Needs::Client, [&](const std::string& t) { return f.cancel(t, "no-such-job"); }},
      {"ListJobs", Needs::Client, [&](const std::string& t) { return f.list(t, true); }},
      {"DownloadArtifact", Needs::Client, [&](const std::string& t) { return f.download(t, doneJob_, 0); }},
      {"LeaseTile", Needs::Worker, [&](const std::string& t) { return f.lease(t, ""); }},
      {"RenewLease", Needs::Worker, [&](const std::string& t) { return f.renew(t, "no-such-lease"); }},
      {"FetchScene", Needs::Worker, [&](const std::string& t) { return f.fetch(t, s_->sceneHash, 0); }},
      {"CompleteTile", Needs::Worker, [&](const std::string& t) { return f.complete(t, {}); }},
      {"FailTile", Needs::Worker, [&](const std::string& t) { return f.fail(t, "no-such-lease", "test"); }},
  };
  enum class Who { None, Wrong, Client, Worker, Admin };
  const std::vector<std::tuple<const char*, Who, std::string>> tokens = {
      {"no token", Who::None, ""},
      {"wrong token", Who::Wrong, kWrongToken},
      {"client token", Who::Client, kClientToken},
      {"worker token", Who::Worker, kWorkerToken},
      {"admin token", Who::Admin, kAdminToken},
  };
  for (const auto& rpc : rpcs) {
    for (const auto& [tokenName, who, token] : tokens) {
      grpc::Status s = rpc.call(token);
      std::string what = std::string(rpc.name) + " with the " + tokenName + ": got " + net::describe(s);
      StatusCode code = s.error_code();
      if (who == Who::None || who == Who::Wrong) {
        EXPECT_EQ(code, StatusCode::UNAUTHENTICATED) << what;
      } else if ((who == Who::Client && rpc.needs == Needs::Worker) ||
                 (who == Who::Worker && rpc.needs == Needs::Client)) {
        EXPECT_EQ(code, StatusCode::PERMISSION_DENIED) << what;
      } else {
        // Allowed: the request itself may be invalid, but it is not refused for its token.
        EXPECT_NE(code, StatusCode::UNAUTHENTICATED) << what;
        EXPECT_NE(code, StatusCode::PERMISSION_DENIED) << what;
      }
    }
  }
  expectIntact("the token matrix");
}

TEST_F(FarmSecurityTest, MalformedAuthorizationIsUnauthenticated) {
  FarmUnderTest& f = *s_->farm;
  const std::vector<std::pair<const char*, std::string>> headers = {
      {"a known token without 'Bearer '", kClientToken},
      {"another scheme", "Basic " + kClientToken},
      {"a lower-case scheme", "bearer " + kClientToken},
      {"'Bearer' alone", "Bearer"},
      {"'Bearer ' and nothing", "Bearer "},
      {"a known token with a suffix", "Bearer " + kClientToken + "x"},
      {"a prefix of a known token", "Bearer " + kClientToken.substr(0, kClientToken.size() - 1)},
  };
  auto stub = pb::Farm::NewStub(net::makeChannel({f.address(), "", ""}));
  for (const auto& [what, header] : headers) {
    grpc::ClientContext ctx;
    f.prepare(ctx, "");
    ctx.AddMetadata("authorization", header);
    pb::ListJobsReply reply;
    grpc::Status s = stub->ListJobs(&ctx, {}, &reply);
    EXPECT_EQ(s.error_code(), StatusCode::UNAUTHENTICATED) << "ListJobs with " << what << ": " << net::describe(s);
  }
  expectIntact("malformed authorization headers");
}

// R18: failed authentications were not limited. An address that fails --auth-failure-limit
// times within a minute is refused everything, a good token included, for
// --auth-lockout-seconds, then served again.
TEST(FarmAuthLimit, AnAddressThatKeepsFailingIsLockedOutForAWhile) {
  const fs::path dir = fs::temp_directory_path() / ("cpvs_farm_auth_limit_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "tokens") << "client " << kClientToken << "\n";
  FarmUnderTest f(dir, "limited", {"--auth-failure-limit", "5", "--auth-lockout-seconds", "2"});
  ASSERT_FALSE(f.address().empty()) << f.log();
  EXPECT_TRUE(f.list(kClientToken, true).ok());
  for (int i = 0; i < 5; ++i) EXPECT_EQ(f.list(kWrongToken, true).error_code(), StatusCode::UNAUTHENTICATED) << i;
  const grpc::Status locked = f.list(kClientToken, true);
  EXPECT_EQ(locked.error_code(), StatusCode::RESOURCE_EXHAUSTED) << net::describe(locked);
  EXPECT_NE(locked.error_message().find("too many failed authentications"), std::string::npos);
  EXPECT_EQ(f.lease(kClientToken, "").error_code(), StatusCode::RESOURCE_EXHAUSTED) << "every service";
  EXPECT_NE(f.log().find("failed to authenticate 5 times"), std::string::npos) << f.log();
  std::this_thread::sleep_for(std::chrono::milliseconds(2300));
  EXPECT_TRUE(f.list(kClientToken, true).ok()) << "served again after the lockout";
  // After a lockout the count starts again; a token of the wrong role is no failed authentication.
  for (int i = 0; i < 4; ++i) EXPECT_EQ(f.lease(kClientToken, "").error_code(), StatusCode::PERMISSION_DENIED);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(f.list(kWrongToken, true).error_code(), StatusCode::UNAUTHENTICATED);
  EXPECT_TRUE(f.list(kClientToken, true).ok()) << "4 failures are under the limit";
  EXPECT_TRUE(f.running());
  fs::remove_all(dir);
}

/// The test scene, then a comment naming `salt` and padding to exactly `size` bytes: a
/// scene of a chosen size and hash.
std::string sceneOfSize(size_t size, const std::string& salt) {
  std::string text = testSceneObj() + "# " + salt + "\n";
  for (size_t pad = size - std::min(size, text.size()); pad > 0;) {
    const size_t n = std::min<size_t>(pad, 80);
    text += std::string(n - 1, '#') + "\n";
    pad -= n;
  }
  return text;
}

// R15: one client could fill the coordinator's disk with uploads and scenes. Its uploads
// in progress and its stored scenes have a quota each; other clients and administrators
// are not held up, and a scene another client stored costs nothing.
TEST(FarmClientQuota, UploadsAndStoredScenesOfOneClientAreBounded) {
  // 10,485 bytes in progress and 15,728 stored per client.
  SuiteState s("quota", {"--client-uploads-mb", "0.01", "--client-scenes-mb", "0.015"});
  ASSERT_EQ(s.problem, "");
  FarmUnderTest& f = *s.farm;
  ASSERT_LT(s.sceneBytes.size(), 2000u);  // the client's first stored scene (the suite's)
  const std::string a = sceneOfSize(8000, "a"), b = sceneOfSize(4000, "b"), c = sceneOfSize(9000, "c"),
                    d = sceneOfSize(8000, "d");
  ASSERT_EQ(a.size(), 8000u);
  pb::UploadSceneReply reply;
  ASSERT_TRUE(f.upload(kClientToken, uploadChunks(hashOf(a), "a.obj", a, 0, 100), &reply).ok());
  EXPECT_FALSE(reply.complete());
  // 8,000 + 4,000 bytes in progress: over.
  grpc::Status over = f.upload(kClientToken, uploadChunks(hashOf(b), "b.obj", b));
  EXPECT_EQ(over.error_code(), StatusCode::RESOURCE_EXHAUSTED) << net::describe(over);
  EXPECT_NE(over.error_message().find("uploads in progress"), std::string::npos) << over.error_message();
  // Another client, and an administrator, are not counted against it.
  ASSERT_TRUE(f.upload(kTeamToken, uploadChunks(hashOf(b), "b.obj", b), &reply).ok());
  EXPECT_TRUE(reply.complete());
  ASSERT_TRUE(f.upload(kAdminToken, uploadChunks(hashOf(c), "c.obj", c, 0, 100), &reply).ok());
  // The client's upload completes: 8,000 more bytes stored, none in progress.
  ASSERT_TRUE(f.upload(kClientToken, uploadChunks(hashOf(a), "a.obj", a, 100), &reply).ok());
  EXPECT_TRUE(reply.complete());
  // Its stored scenes and one more of 8,000 bytes: over.
  over = f.upload(kClientToken, uploadChunks(hashOf(d), "d.obj", d));
  EXPECT_EQ(over.error_code(), StatusCode::RESOURCE_EXHAUSTED) << net::describe(over);
  EXPECT_NE(over.error_message().find("stored scenes"), std::string::npos) << over.error_message();
  pb::UploadStatus status;
  ASSERT_TRUE(f.uploadStatus(kClientToken, hashOf(d), &status).ok());
  EXPECT_FALSE(status.known()) << "nothing of the refused upload is kept";
  // A scene another client stored is no new bytes: the client still gets it.
  ASSERT_TRUE(f.upload(kClientToken, uploadChunks(hashOf(b), "b.obj", b), &reply).ok());
  EXPECT_TRUE(reply.complete());
  // The owners outlive a restart: the client is still over its quota.
  s.farm.reset();
  fs::remove(s.dir / "quota.address");  // the next one's, not the last one's
  s.farm = std::make_unique<FarmUnderTest>(s.dir, "quota", std::vector<std::string>{"--client-uploads-mb", "0.01",
                                                                                     "--client-scenes-mb", "0.015"});
  over = s.farm->upload(kClientToken, uploadChunks(hashOf(d), "d.obj", d));
  EXPECT_EQ(over.error_code(), StatusCode::RESOURCE_EXHAUSTED) << net::describe(over);
  EXPECT_TRUE(s.farm->upload(kTeamToken, uploadChunks(hashOf(d), "d.obj", d), &reply).ok());
  EXPECT_TRUE(s.farm->running());
}

TEST_F(FarmSecurityTest, MalformedRequestsGetTheirStatusAndChangeNothing) {
  FarmUnderTest& f = *s_->farm;
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  int submitted = 0;
  auto submitWith = [&](const std::function<void(pb::SubmitBakeRequest&)>& edit) {
    pb::SubmitBakeRequest r = s_->request("bad-input-" + std::to_string(++submitted));
    edit(r);
    return f.submit(kClientToken, r);
  };
  auto sunDir = [](pb::SubmitBakeRequest& r, double x, double y, double z) {
    r.mutable_spec()->mutable_sun_direction()->set_x(x);
    r.mutable_spec()->mutable_sun_direction()->set_y(y);
    r.mutable_spec()->mutable_sun_direction()->set_z(z);
  };
  auto sunAngles = [](pb::SubmitBakeRequest& r, double elevation, double azimuth) {
    r.mutable_spec()->mutable_sun_angles()->set_elevation_deg(elevation);
    r.mutable_spec()->mutable_sun_angles()->set_azimuth_deg(azimuth);
  };
  auto header = [](const std::string& hash, const std::string& name, uint64_t total, uint64_t offset,
                   const std::string& data) {
    pb::UploadSceneChunk c;
    c.set_scene_hash(hash);
    c.set_file_name(name);
    c.set_total_size(total);
    c.set_offset(offset);
    c.set_data(data);
    return c;
  };
  auto body = [](uint64_t offset, const std::string& data) {
    pb::UploadSceneChunk c;
    c.set_offset(offset);
    c.set_data(data);
    return c;
  };
  const std::string unknownHash(32, 'a');

  // A tile of the stored job, leased by the test as a worker, and valid results: its own
  // and another tile's.
  pb::TileLease lease;
  ASSERT_TRUE(f.lease(kWorkerToken, "security-stub", &lease).ok());
  ASSERT_TRUE(lease.granted());
  ASSERT_EQ(lease.job_id(), storedJob_);
  const std::string good = s_->bake(lease, lease.tile_x(), lease.tile_y());
  const std::string otherTile = s_->bake(lease, lease.tile_x() ^ 1, lease.tile_y());
  const fs::path tileFile = f.dataDir() / "tiles" / storedJob_ / (std::to_string(lease.tile_index()) + ".cpvt");
  auto expectTileNotDone = [&](const std::string& after) {
    EXPECT_EQ(f.job(storedJob_).tiles_done(), 0u) << after;
    EXPECT_FALSE(fs::exists(tileFile)) << after;
    pb::RenewReply renewed;
    EXPECT_TRUE(f.renew(kWorkerToken, lease.lease_id(), &renewed).ok() && renewed.valid()) << after;
  };

  struct BadInput {
    std::string what;
    StatusCode expected;  // the documented status
    std::function<grpc::Status()> send;
  };
  const std::vector<BadInput> cases = {
      // --- SubmitBake: the spec is checked before anything is stored -------------------
      {"SubmitBake: sun_direction (NaN, -1, 0)", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { sunDir(r, nan, -1, 0); }); }},
      {"SubmitBake: sun_direction (0, 0, 0)", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { sunDir(r, 0, 0, 0); }); }},
      {"SubmitBake: sun_direction (inf, -1, 0)", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { sunDir(r, inf, -1, 0); }); }},
      {"SubmitBake: sun_direction whose length overflows (1e308, -1e308, 1e308) is still a direction", StatusCode::OK,
       [&] {
         pb::SubmitBakeRequest r = s_->request("huge-direction", 32);
         sunDir(r, 1e308, -1e308, 1e308);
         pb::JobStatus job;
         grpc::Status s = f.submit(kClientToken, r, &job);
         if (s.ok()) {
           EXPECT_TRUE(f.cancel(kClientToken, job.job_id()).ok());  // gives its place back
         }
         return s;
       }},
      {"SubmitBake: sun elevation -5", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { sunAngles(r, -5, 0); }); }},
      {"SubmitBake: sun elevation 91", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { sunAngles(r, 91, 0); }); }},
      {"SubmitBake: sun azimuth NaN", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { sunAngles(r, 35, nan); }); }},
      {"SubmitBake: no sun at all", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { r.mutable_spec()->clear_sun_direction(); }); }},
      {"SubmitBake: resolution \"3\" (not a power of two)", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { r.mutable_spec()->set_resolution("3"); }); }},
      {"SubmitBake: resolution \"1073741824\" (2^30)", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { r.mutable_spec()->set_resolution("1073741824"); }); }},
      {"SubmitBake: resolution \"1048576K\" (2^30 with a suffix)", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { r.mutable_spec()->set_resolution("1048576K"); }); }},
      {"SubmitBake: resolution \"abc\"", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { r.mutable_spec()->set_resolution("abc"); }); }},
      {"SubmitBake: resolution \"\"", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { r.mutable_spec()->set_resolution(""); }); }},
      {"SubmitBake: resolution 8K above --max-resolution 4K", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { r.mutable_spec()->set_resolution("8K"); }); }},
      {"SubmitBake: resolution 32 below the farm's 64", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { r.mutable_spec()->set_resolution("32"); }); }},
      {"SubmitBake: tile_size 100", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { r.mutable_spec()->mutable_options()->set_tile_size(100); }); }},
      {"SubmitBake: tile_size 2^31", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { r.mutable_spec()->mutable_options()->set_tile_size(1u << 31); }); }},
      {"SubmitBake: options.closed = 7 (an enum value the contract does not name)", StatusCode::INVALID_ARGUMENT,
       [&] {
         // As the wire carries it: field 1, varint 7 (proto3 keeps unknown enum values).
         const std::string wire("\x08\x07", 2);
         return submitWith([&](auto& r) { r.mutable_spec()->mutable_options()->ParseFromString(wire); });
       }},
      {"SubmitBake: options.compress = -1", StatusCode::INVALID_ARGUMENT,
       [&] {
         pb::BakeOptions o;
         o.GetReflection()->SetEnumValue(&o, o.GetDescriptor()->FindFieldByName("compress"), -1);
         return submitWith([&](auto& r) { *r.mutable_spec()->mutable_options() = o; });
       }},
      {"SubmitBake: empty request_id", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { r.set_request_id(""); }); }},
      {"SubmitBake: request_id of 129 characters", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { r.set_request_id(std::string(129, 'r')); }); }},
      {"SubmitBake: priority 1001", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { r.mutable_spec()->set_priority(1001); }); }},
      {"SubmitBake: name of 257 characters", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { r.mutable_spec()->set_name(std::string(257, 'n')); }); }},
      {"SubmitBake: unknown scene hash (32 hex digits)", StatusCode::NOT_FOUND,
       [&] { return submitWith([&](auto& r) { r.mutable_spec()->set_scene_hash(unknownHash); }); }},
      {"SubmitBake: malformed scene hash \"xyz\"", StatusCode::INVALID_ARGUMENT,
       [&] { return submitWith([&](auto& r) { r.mutable_spec()->set_scene_hash("xyz"); }); }},
      {"SubmitBake: scene hash in upper case", StatusCode::INVALID_ARGUMENT,
       [&] {
         std::string upper = s_->sceneHash;
         for (char& c : upper) c = char(std::toupper(static_cast<unsigned char>(c)));
         return submitWith([&](auto& r) { r.mutable_spec()->set_scene_hash(upper); });
       }},
      {"SubmitBake: request_id reused with a different spec", StatusCode::ALREADY_EXISTS,
       [&] {
         // The same request again is the same job (a retry), not a new one.
         pb::JobStatus again;
         EXPECT_TRUE(f.submit(kClientToken, s_->request(kStoredRequest, 32), &again).ok());
         EXPECT_EQ(again.job_id(), storedJob_);
         pb::SubmitBakeRequest r = s_->request(kStoredRequest, 32);
         r.mutable_spec()->set_resolution("128");
         return f.submit(kClientToken, r);
       }},
      {"SubmitBake: more unfinished jobs than --max-jobs 3", StatusCode::RESOURCE_EXHAUSTED,
       [&] {
         // The stored job is unfinished: two more fit, the third does not.
         std::vector<std::string> made;
         grpc::Status s;
         for (int i = 0; i < 5; ++i) {
           pb::JobStatus job;
           s = f.submit(kClientToken, s_->request("quota-" + std::to_string(i), 32), &job);
           if (!s.ok()) break;
           made.push_back(job.job_id());
         }
         EXPECT_EQ(made.size(), 2u);
         // Cancelled jobs give their places back.
         for (const auto& id : made) {
           pb::JobStatus cancelled;
           EXPECT_TRUE(f.cancel(kClientToken, id, &cancelled).ok());
           EXPECT_EQ(cancelled.state(), pb::JOB_CANCELLED);
         }
         pb::JobStatus later;
         EXPECT_TRUE(f.submit(kClientToken, s_->request("quota-after-cancel", 32), &later).ok());
         EXPECT_TRUE(f.cancel(kClientToken, later.job_id()).ok());
         return s;
       }},

      // --- UploadScene -----------------------------------------------------------------
      {"UploadScene: an OBJ with vertices and no faces (imports to nothing)", StatusCode::INVALID_ARGUMENT,
       [&] {
         const std::string empty = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
         const std::string hash = hashOf(empty);
         pb::UploadSceneReply reply;
         grpc::Status s = f.upload(kClientToken, uploadChunks(hash, "empty.obj", empty), &reply);
         // The message names the caller's file, not the server's data folder.
         EXPECT_NE(s.error_message().find("empty.obj"), std::string::npos) << s.error_message();
         EXPECT_EQ(s.error_message().find(f.dataDir().string()), std::string::npos) << s.error_message();
         pb::UploadStatus st;
         EXPECT_TRUE(f.uploadStatus(kClientToken, hash, &st).ok());
         EXPECT_FALSE(st.complete());
         EXPECT_EQ(st.received(), 0u);  // uploaded again from the start, if ever
         // Nothing can be baked or fetched from it.
         EXPECT_EQ(submitWith([&](auto& r) { r.mutable_spec()->set_scene_hash(hash); }).error_code(),
                   StatusCode::NOT_FOUND);
         EXPECT_EQ(f.fetch(kWorkerToken, hash, 0).error_code(), StatusCode::NOT_FOUND);
         return s;
       }},
      {"UploadScene: a new upload whose first chunk is at byte 10", StatusCode::FAILED_PRECONDITION,
       [&] {
         const std::string bytes = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
         return f.upload(kClientToken, {header(hashOf(bytes), "tri.obj", bytes.size(), 10, bytes.substr(10))});
       }},
      {"UploadScene: a later chunk at the wrong offset", StatusCode::INVALID_ARGUMENT,
       [&] {
         const std::string bytes = "v 0 0 0\nv 2 0 0\nv 0 2 0\nf 1 2 3\n";
         const std::string hash = hashOf(bytes);
         grpc::Status s = f.upload(kClientToken, {header(hash, "gap.obj", bytes.size(), 0, bytes.substr(0, 4)),
                                                  body(10, bytes.substr(10))});
         pb::UploadStatus st;
         EXPECT_TRUE(f.uploadStatus(kClientToken, hash, &st).ok());
         EXPECT_EQ(st.received(), 4u);  // what came in order is kept
         EXPECT_FALSE(st.complete());
         EXPECT_EQ(f.fetch(kWorkerToken, hash, 0).error_code(), StatusCode::NOT_FOUND);  // not a scene yet
         return s;
       }},
      {"UploadScene: bytes that do not match the announced hash", StatusCode::DATA_LOSS,
       [&] {
         const std::string bytes = "v 0 0 0\nv 3 0 0\nv 0 3 0\nf 1 2 3\n";
         const std::string hash = hashOf(bytes + "\n");
         grpc::Status s = f.upload(kClientToken, uploadChunks(hash, "lie.obj", bytes));
         pb::UploadStatus st;
         EXPECT_TRUE(f.uploadStatus(kClientToken, hash, &st).ok());
         EXPECT_FALSE(st.complete());
         EXPECT_EQ(st.received(), 0u);
         return s;
       }},
      {"UploadScene: a stream that ends before total_size (OK, resumable)", StatusCode::OK,
       [&] {
         Scene box;
         appendBox(box, {0, 0, 0}, {1, 1, 1});
         const std::string bytes = objText(box, "resumed");
         const std::string hash = hashOf(bytes);
         const size_t half = bytes.size() / 2;
         pb::UploadSceneReply reply;
         grpc::Status s = f.upload(kClientToken, uploadChunks(hash, "resumed.obj", bytes, 0, half), &reply);
         EXPECT_FALSE(reply.complete());
         EXPECT_EQ(reply.received(), half);
         pb::UploadStatus st;
         EXPECT_TRUE(f.uploadStatus(kClientToken, hash, &st).ok());
         EXPECT_TRUE(st.known());
         EXPECT_EQ(st.received(), half);
         EXPECT_EQ(st.total_size(), bytes.size());
         EXPECT_FALSE(st.complete());
         // Resuming anywhere but at the received bytes is refused, and loses nothing...
         EXPECT_EQ(f.upload(kClientToken, uploadChunks(hash, "resumed.obj", bytes, 0)).error_code(),
                   StatusCode::FAILED_PRECONDITION);
         EXPECT_TRUE(f.uploadStatus(kClientToken, hash, &st).ok());
         EXPECT_EQ(st.received(), half);
         // ... resuming there completes it.
         pb::UploadSceneReply resumed;
         EXPECT_TRUE(f.upload(kClientToken, uploadChunks(hash, "resumed.obj", bytes, half), &resumed).ok());
         EXPECT_TRUE(resumed.complete());
         EXPECT_EQ(resumed.triangles(), 12u);
         std::string fetched;
         EXPECT_TRUE(f.fetch(kWorkerToken, hash, 0, &fetched).ok());
         EXPECT_EQ(fetched, bytes);
         return s;
       }},
      {"UploadScene: a chunk of kChunkBytes + 1 bytes", StatusCode::INVALID_ARGUMENT,
       [&] {
         return f.upload(kClientToken, {header(std::string(32, 'b'), "big.obj", net::kChunkBytes, 0,
                                               std::string(net::kChunkBytes + 1, 'v'))});
       }},
      {"UploadScene: a 2 MiB message, over the server's message limit", StatusCode::RESOURCE_EXHAUSTED,
       [&] {
         // A channel that sends what the farm's channels never would: gRPC's own receive
         // limit on the server refuses it.
         grpc::ChannelArguments args;
         args.SetInt(GRPC_ARG_ENABLE_HTTP_PROXY, 0);
         args.SetMaxSendMessageSize(8 << 20);
         auto big = pb::Farm::NewStub(grpc::CreateCustomChannel(f.address(), grpc::InsecureChannelCredentials(), args));
         const std::string twoMiB(2 << 20, 'v');
         return f.upload(kClientToken, {header(std::string(32, 'c'), "huge.obj", 1 << 20, 0, twoMiB)}, nullptr,
                         big.get());
       }},
      {"UploadScene: total_size above --max-upload-mb 1", StatusCode::RESOURCE_EXHAUSTED,
       [&] {
         return f.upload(kClientToken, {header(std::string(32, 'd'), "large.obj", (1 << 20) + 1, 0, "v 0 0 0\n")});
       }},
      {"UploadScene: a file name without extension", StatusCode::INVALID_ARGUMENT,
       [&] { return f.upload(kClientToken, uploadChunks(std::string(32, 'e'), "scene", "v 0 0 0\n")); }},
      {"UploadScene: a file name whose extension is not letters and digits", StatusCode::INVALID_ARGUMENT,
       [&] { return f.upload(kClientToken, uploadChunks(std::string(32, 'e'), "scene.o%2fbj", "v 0 0 0\n")); }},
      {"UploadScene: an empty stream", StatusCode::INVALID_ARGUMENT, [&] { return f.upload(kClientToken, {}); }},
      {"UploadScene: total_size 0", StatusCode::INVALID_ARGUMENT,
       [&] { return f.upload(kClientToken, {header(std::string(32, 'f'), "zero.obj", 0, 0, "")}); }},
      {"UploadScene: data past the announced total_size", StatusCode::INVALID_ARGUMENT,
       [&] { return f.upload(kClientToken, {header(std::string(32, 'f'), "past.obj", 4, 0, "v 0 0 0\n")}); }},
      {"UploadScene: a second scene hash in one stream", StatusCode::INVALID_ARGUMENT,
       [&] {
         pb::UploadSceneChunk second = body(4, "0 0\n");
         second.set_scene_hash(std::string(32, '1'));
         return f.upload(kClientToken, {header(std::string(32, '0'), "two.obj", 8, 0, "v 0 "), second});
       }},
      {"UploadScene: the stored scene's hash with other bytes (OK, the stored file stays)", StatusCode::OK,
       [&] {
         const std::string other = "v 0 0 0\nv 9 0 0\nv 0 9 0\nf 1 2 3\n";
         pb::UploadSceneReply reply;
         grpc::Status s = f.upload(kClientToken, uploadChunks(s_->sceneHash, "scene.obj", other), &reply);
         EXPECT_TRUE(reply.complete());
         std::string fetched;
         EXPECT_TRUE(f.fetch(kWorkerToken, s_->sceneHash, 0, &fetched).ok());
         EXPECT_EQ(fetched, s_->sceneBytes);
         return s;
       }},
      {"GetUploadStatus: malformed hash \"xyz\"", StatusCode::INVALID_ARGUMENT,
       [&] { return f.uploadStatus(kClientToken, "xyz"); }},
      {"GetUploadStatus: unknown hash (OK, known = false)", StatusCode::OK,
       [&] {
         pb::UploadStatus st;
         grpc::Status s = f.uploadStatus(kClientToken, unknownHash, &st);
         EXPECT_FALSE(st.known());
         return s;
       }},

      // --- Jobs and artifacts ----------------------------------------------------------
      {"WatchJob: unknown job", StatusCode::NOT_FOUND, [&] { return f.watch(kClientToken, "j0123456789abcdef"); }},
      {"CancelJob: unknown job", StatusCode::NOT_FOUND, [&] { return f.cancel(kClientToken, "j0123456789abcdef"); }},
      {"CancelJob: a done job (OK, it stays done)", StatusCode::OK,
       [&] {
         pb::JobStatus st;
         grpc::Status s = f.cancel(kClientToken, doneJob_, &st);
         EXPECT_EQ(st.state(), pb::JOB_DONE);
         return s;
       }},
      {"DownloadArtifact: unknown job", StatusCode::NOT_FOUND,
       [&] { return f.download(kClientToken, "j0123456789abcdef", 0); }},
      {"DownloadArtifact: a job that is not done", StatusCode::FAILED_PRECONDITION,
       [&] { return f.download(kClientToken, storedJob_, 0); }},
      {"DownloadArtifact: offset past the end of a done job's artifact", StatusCode::OUT_OF_RANGE,
       [&] {
         std::string bytes, checksum;
         EXPECT_TRUE(f.download(kClientToken, doneJob_, 0, &bytes, &checksum).ok());
         EXPECT_EQ(hashOf(bytes), checksum);
         EXPECT_EQ(bytes.size(), f.job(doneJob_).file_bytes());
         return f.download(kClientToken, doneJob_, bytes.size() + 1);
       }},

      // --- Workers ---------------------------------------------------------------------
      {"CompleteTile: a corrupt sub-DAG with the correct checksum of its bytes", StatusCode::INVALID_ARGUMENT,
       [&] {
         std::string garbage = good;
         for (size_t i = 16; i < garbage.size(); i += 7) garbage[i] = char(garbage[i] ^ 0x5a);
         grpc::Status s = f.complete(kWorkerToken, resultChunks(lease.lease_id(), garbage));
         expectTileNotDone("a corrupt sub-DAG");
         return s;
       }},
      {"CompleteTile: bytes that are no sub-DAG at all", StatusCode::INVALID_ARGUMENT,
       [&] {
         grpc::Status s = f.complete(kWorkerToken, resultChunks(lease.lease_id(), std::string(1000, '\0')));
         expectTileNotDone("zero bytes for a sub-DAG");
         return s;
       }},
      {"CompleteTile: a valid sub-DAG of another tile", StatusCode::INVALID_ARGUMENT,
       [&] {
         grpc::Status s = f.complete(kWorkerToken, resultChunks(lease.lease_id(), otherTile));
         expectTileNotDone("another tile's sub-DAG");
         return s;
       }},
      {"CompleteTile: data that does not match its checksum", StatusCode::DATA_LOSS,
       [&] {
         grpc::Status s = f.complete(kWorkerToken, resultChunks(lease.lease_id(), good, hashOf(good + "x")));
         expectTileNotDone("a checksum mismatch");
         return s;
       }},
      {"CompleteTile: fewer bytes than total_size", StatusCode::DATA_LOSS,
       [&] {
         auto chunks = resultChunks(lease.lease_id(), good);
         chunks[0].set_total_size(good.size() + 10);
         grpc::Status s = f.complete(kWorkerToken, chunks);
         expectTileNotDone("a truncated result");
         return s;
       }},
      {"CompleteTile: total_size 0", StatusCode::INVALID_ARGUMENT,
       [&] {
         auto chunks = resultChunks(lease.lease_id(), good);
         chunks[0].set_total_size(0);
         return f.complete(kWorkerToken, chunks);
       }},
      {"CompleteTile: a NaN stage time", StatusCode::INVALID_ARGUMENT,
       [&] {
         auto chunks = resultChunks(lease.lease_id(), good);
         chunks[0].mutable_stages(0)->set_seconds(nan);
         grpc::Status s = f.complete(kWorkerToken, chunks);
         expectTileNotDone("a NaN stage time");
         return s;
       }},
      {"CompleteTile: an unknown lease (valid data)", StatusCode::NOT_FOUND,
       [&] { return f.complete(kWorkerToken, resultChunks("l0123456789abcdef", good)); }},
      {"CompleteTile: an empty stream", StatusCode::INVALID_ARGUMENT, [&] { return f.complete(kWorkerToken, {}); }},
      {"RenewLease: an unknown lease (OK, valid = false)", StatusCode::OK,
       [&] {
         pb::RenewReply r;
         grpc::Status s = f.renew(kWorkerToken, "l0123456789abcdef", &r);
         EXPECT_FALSE(r.valid());
         return s;
       }},
      {"LeaseTile: empty worker_id", StatusCode::INVALID_ARGUMENT, [&] { return f.lease(kWorkerToken, ""); }},
      {"LeaseTile: worker_id of 129 characters", StatusCode::INVALID_ARGUMENT,
       [&] { return f.lease(kWorkerToken, std::string(129, 'w')); }},
      {"FailTile: an unknown lease", StatusCode::NOT_FOUND,
       [&] { return f.fail(kWorkerToken, "l0123456789abcdef", "no such lease"); }},
      {"FetchScene: unknown scene", StatusCode::NOT_FOUND, [&] { return f.fetch(kWorkerToken, unknownHash, 0); }},
      {"FetchScene: malformed hash", StatusCode::INVALID_ARGUMENT, [&] { return f.fetch(kWorkerToken, "../x", 0); }},
      {"FetchScene: offset past the end", StatusCode::OUT_OF_RANGE,
       [&] { return f.fetch(kWorkerToken, s_->sceneHash, s_->sceneBytes.size() + 1); }},
  };
  ASSERT_GE(cases.size(), 20u);
  for (const auto& c : cases) {
    grpc::Status s = c.send();
    EXPECT_EQ(s.error_code(), c.expected)
        << c.what << ": expected " << codeName(c.expected) << ", got " << net::describe(s);
    expectIntact(c.what);
    if (::testing::Test::HasFatalFailure()) return;
  }

  // The lease outlived every bad result: the real one is taken.
  pb::CompleteReply done;
  grpc::Status s = f.complete(kWorkerToken, resultChunks(lease.lease_id(), good), &done);
  ASSERT_TRUE(s.ok()) << net::describe(s);
  EXPECT_TRUE(done.accepted());
  EXPECT_EQ(f.job(storedJob_).tiles_done(), 1u);
}

// R28: any client token could list, follow, cancel and download every job. A client sees
// and touches its own jobs only (tokens of one owner share theirs); an administrator all.
TEST_F(FarmSecurityTest, R28_AClientSeesAndTouchesOnlyItsOwnJobs) {
  FarmUnderTest& f = *s_->farm;
  pb::JobStatus theirs;
  ASSERT_TRUE(f.submit(kTeamToken, s_->request("the-teams-job", 32), &theirs).ok());
  auto listed = [&](const std::string& token) {
    pb::ListJobsReply all;
    EXPECT_TRUE(f.list(token, true, &all).ok());
    std::set<std::string> ids;
    for (const auto& j : all.jobs()) ids.insert(j.job_id());
    return ids;
  };
  EXPECT_EQ(listed(kTeamToken), std::set<std::string>{theirs.job_id()});
  EXPECT_EQ(listed(kTeamMateToken), std::set<std::string>{theirs.job_id()});
  const std::set<std::string> mine = listed(kClientToken), everything = listed(kAdminToken);
  EXPECT_EQ(mine.count(theirs.job_id()), 0u);
  EXPECT_EQ(mine.count(doneJob_), 1u);
  EXPECT_EQ(mine.count(storedJob_), 1u);
  for (const std::string& id : {theirs.job_id(), doneJob_, storedJob_}) EXPECT_EQ(everything.count(id), 1u) << id;
  // Another client's job, by its id: PERMISSION_DENIED, and nothing changes.
  EXPECT_EQ(f.cancel(kClientToken, theirs.job_id()).error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(f.watch(kClientToken, theirs.job_id()).error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(f.download(kTeamToken, doneJob_, 0).error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(f.cancel(kTeamMateToken, storedJob_).error_code(), grpc::StatusCode::PERMISSION_DENIED);
  // A request id another client used is taken, without saying whose job it names.
  const grpc::Status taken = f.submit(kClientToken, s_->request("the-teams-job", 32));
  EXPECT_EQ(taken.error_code(), grpc::StatusCode::ALREADY_EXISTS);
  EXPECT_EQ(taken.error_message().find(theirs.job_id()), std::string::npos) << taken.error_message();
  // Nor may a client take the name of a track's keyframe job (it would stall that track).
  EXPECT_EQ(f.submit(kClientToken, s_->request("keyframe-0123456789abcdef0123456789abcdef", 32)).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  // The owner's other token and the administrator may.
  std::string bytes;
  EXPECT_TRUE(f.download(kAdminToken, doneJob_, 0, &bytes).ok());
  EXPECT_GT(bytes.size(), 0u);
  pb::JobStatus cancelled;
  EXPECT_TRUE(f.cancel(kTeamMateToken, theirs.job_id(), &cancelled).ok());
  EXPECT_EQ(cancelled.state(), pb::JOB_CANCELLED);
  expectIntact("R28");
}

TEST_F(FarmSecurityTest, ConcurrentRetriesOfOneRequestGiveOneJob) {
  // A client that times out and retries while its first call is still being served sends
  // the same request twice at once: both must get the same job, and only one is created.
  FarmUnderTest& f = *s_->farm;
  const pb::SubmitBakeRequest request = s_->request("retried-at-once", 32);
  constexpr int kCalls = 8;
  std::vector<grpc::Status> statuses(kCalls);
  std::vector<pb::JobStatus> jobs(kCalls);
  std::vector<std::thread> threads;
  for (int i = 0; i < kCalls; ++i)
    threads.emplace_back([&, i] { statuses[size_t(i)] = f.submit(kClientToken, request, &jobs[size_t(i)]); });
  for (auto& t : threads) t.join();
  for (int i = 0; i < kCalls; ++i) {
    EXPECT_TRUE(statuses[size_t(i)].ok()) << "call " << i << ": " << net::describe(statuses[size_t(i)]);
    EXPECT_EQ(jobs[size_t(i)].job_id(), jobs[0].job_id()) << "call " << i;
  }
  pb::ListJobsReply all;
  ASSERT_TRUE(f.list(kClientToken, true, &all).ok());
  int made = 0;
  for (const auto& j : all.jobs()) made += j.request_id() == request.request_id();
  EXPECT_EQ(made, 1);
  EXPECT_TRUE(f.cancel(kClientToken, jobs[0].job_id()).ok());
  expectIntact("concurrent retries of one request");
}

TEST_F(FarmSecurityTest, ConcurrentSubmitsStayWithinMaxJobs) {
  // --max-jobs 3 with the stored job unfinished: of many different jobs submitted at once,
  // two are taken and the others get RESOURCE_EXHAUSTED.
  FarmUnderTest& f = *s_->farm;
  constexpr int kCalls = 8;
  std::vector<grpc::Status> statuses(kCalls);
  std::vector<pb::JobStatus> jobs(kCalls);
  std::vector<std::thread> threads;
  for (int i = 0; i < kCalls; ++i)
    threads.emplace_back([&, i] {
      statuses[size_t(i)] = f.submit(kClientToken, s_->request("at-once-" + std::to_string(i), 32), &jobs[size_t(i)]);
    });
  for (auto& t : threads) t.join();
  int taken = 0;
  for (size_t i = 0; i < kCalls; ++i) {
    if (statuses[i].ok()) {
      ++taken;
      EXPECT_TRUE(f.cancel(kClientToken, jobs[i].job_id()).ok());
    } else {
      EXPECT_EQ(statuses[i].error_code(), StatusCode::RESOURCE_EXHAUSTED) << net::describe(statuses[i]);
    }
  }
  EXPECT_EQ(taken, 2);
  expectIntact("concurrent submits");
}

// =======================================================================================
// Lease rules, with the test as the only worker, on a coordinator with 1-second leases.

class FarmLeaseRulesTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { s_ = new SuiteState("leases", {"--lease-seconds", "1", "--max-attempts", "3"}); }
  static void TearDownTestSuite() {
    delete s_;
    s_ = nullptr;
  }
  void SetUp() override { ASSERT_TRUE(s_->problem.empty()) << s_->problem; }
  /// Jobs a test submitted are cancelled when it ends, so that the next one leases only its own.
  void TearDown() override {
    for (const auto& id : jobs_) s_->farm->cancel(kClientToken, id);
  }

  std::string submit(const std::string& requestId, uint32_t tileSize, int priority) {
    pb::JobStatus job;
    grpc::Status s = s_->farm->submit(kClientToken, s_->request(requestId, tileSize, priority), &job);
    EXPECT_TRUE(s.ok()) << net::describe(s);
    jobs_.push_back(job.job_id());
    return job.job_id();
  }

  static SuiteState* s_;
  std::vector<std::string> jobs_;
};
SuiteState* FarmLeaseRulesTest::s_ = nullptr;

TEST_F(FarmLeaseRulesTest, ExpiredLeaseIsLeasedAgainAndTheFirstResultWins) {
  FarmUnderTest& f = *s_->farm;
  const std::string job = submit("expiring", 32, 0);  // 4 tiles
  std::vector<pb::TileLease> first(4);
  for (uint64_t t = 0; t < 4; ++t) {
    ASSERT_TRUE(f.lease(kWorkerToken, "slow-worker", &first[t]).ok());
    ASSERT_TRUE(first[t].granted());
    EXPECT_EQ(first[t].job_id(), job);
    EXPECT_EQ(first[t].tile_index(), t);
  }
  // Two valid results for tile 0: the job's, and one of another light (valid, different).
  const std::string mine = s_->bake(first[0], 0, 0);
  const std::string other = s_->bake(first[0], 0, 0, true);
  ASSERT_NE(mine, other);

  // Nobody renews: the leases expire and tile 0 (the first in order) is handed out again.
  pb::TileLease second;
  ASSERT_TRUE(f.leaseWithin("fast-worker", 10, &second)) << f.log();
  EXPECT_EQ(second.job_id(), job);
  EXPECT_EQ(second.tile_index(), 0u);
  EXPECT_NE(second.lease_id(), first[0].lease_id());
  pb::RenewReply renewed;
  ASSERT_TRUE(f.renew(kWorkerToken, first[0].lease_id(), &renewed).ok());
  EXPECT_FALSE(renewed.valid()) << "an expired lease cannot be renewed";

  // The late result of the first lease is taken: no other result was.
  pb::CompleteReply late;
  grpc::Status s = f.complete(kWorkerToken, resultChunks(first[0].lease_id(), mine), &late);
  ASSERT_TRUE(s.ok()) << net::describe(s);
  EXPECT_TRUE(late.accepted());
  EXPECT_EQ(f.job(job).tiles_done(), 1u);
  const fs::path tileFile = f.dataDir() / "tiles" / job / "0.cpvt";
  EXPECT_TRUE(fileText(tileFile) == mine) << "the accepted result is not the tile's file";

  // The second lease's result is declined, and does not replace the one taken.
  pb::CompleteReply declined;
  s = f.complete(kWorkerToken, resultChunks(second.lease_id(), other), &declined);
  ASSERT_TRUE(s.ok()) << net::describe(s);
  EXPECT_FALSE(declined.accepted());
  EXPECT_EQ(f.job(job).tiles_done(), 1u);
  EXPECT_TRUE(fileText(tileFile) == mine) << "a declined result replaced the accepted tile's file";
  ASSERT_TRUE(f.renew(kWorkerToken, second.lease_id(), &renewed).ok());
  EXPECT_FALSE(renewed.valid()) << "the lease of a done tile stays valid";
}

TEST_F(FarmLeaseRulesTest, RenewedLeaseOutlivesItsLengthAndEndsWithItsJob) {
  FarmUnderTest& f = *s_->farm;
  const std::string job = submit("renewed", 0, 0);  // 1 tile
  pb::TileLease lease;
  ASSERT_TRUE(f.lease(kWorkerToken, "steady-worker", &lease).ok());
  ASSERT_TRUE(lease.granted());
  // Renewed every 300 ms for 1.5 leases' length: never expires, never handed out again.
  for (int i = 0; i < 5; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    pb::RenewReply r;
    ASSERT_TRUE(f.renew(kWorkerToken, lease.lease_id(), &r).ok());
    EXPECT_TRUE(r.valid()) << "renewal " << i;
    EXPECT_GT(r.deadline_unix_ms(), lease.deadline_unix_ms());
    pb::TileLease again;
    ASSERT_TRUE(f.lease(kWorkerToken, "other-worker", &again).ok());
    EXPECT_FALSE(again.granted()) << "a renewed tile was leased again";
  }
  // The job ends: the lease cannot be renewed, and a result is declined.
  ASSERT_TRUE(f.cancel(kClientToken, job).ok());
  pb::RenewReply r;
  ASSERT_TRUE(f.renew(kWorkerToken, lease.lease_id(), &r).ok());
  EXPECT_FALSE(r.valid());
  pb::CompleteReply reply;
  grpc::Status s = f.complete(kWorkerToken, resultChunks(lease.lease_id(), s_->bake(lease, 0, 0)), &reply);
  ASSERT_TRUE(s.ok()) << net::describe(s);
  EXPECT_FALSE(reply.accepted());
}

TEST_F(FarmLeaseRulesTest, TileFailedMaxAttemptsTimesFailsItsJob) {
  FarmUnderTest& f = *s_->farm;
  const std::string job = submit("failing", 0, 0);  // 1 tile
  pb::TileLease lease;
  for (int attempt = 1; attempt <= 3; ++attempt) {
    ASSERT_TRUE(f.lease(kWorkerToken, "broken-worker", &lease).ok());
    ASSERT_TRUE(lease.granted()) << "attempt " << attempt;
    EXPECT_EQ(lease.job_id(), job);
    grpc::Status s = f.fail(kWorkerToken, lease.lease_id(), "out of memory on attempt " + std::to_string(attempt));
    ASSERT_TRUE(s.ok()) << net::describe(s);
    pb::JobStatus st = f.job(job);
    EXPECT_EQ(st.state(), attempt < 3 ? pb::JOB_RUNNING : pb::JOB_FAILED) << "after attempt " << attempt;
  }
  pb::JobStatus st;
  ASSERT_TRUE(f.watch(kClientToken, job, &st).ok());
  EXPECT_EQ(st.state(), pb::JOB_FAILED);
  EXPECT_NE(st.error().find("failed 3 times"), std::string::npos) << st.error();
  EXPECT_NE(st.error().find("out of memory on attempt 3"), std::string::npos) << st.error();
  // Nothing of it is handed out any more, and a late failure of its last lease changes nothing.
  pb::TileLease none;
  ASSERT_TRUE(f.lease(kWorkerToken, "broken-worker", &none).ok());
  EXPECT_FALSE(none.granted());
  EXPECT_TRUE(f.fail(kWorkerToken, lease.lease_id(), "again").ok());
  EXPECT_EQ(f.job(job).error(), st.error());
  EXPECT_EQ(f.download(kClientToken, job, 0).error_code(), StatusCode::FAILED_PRECONDITION);
}

// R10: a coordinator stopped (SIGSTOP, a stalled VM) for three 1-second leases expired
// every lease at its first round after it came back, though its worker kept trying to
// renew; each counted an attempt.
TEST_F(FarmLeaseRulesTest, R10_APausedCoordinatorExpiresNoLeaseItsWorkerKeptRenewing) {
  FarmUnderTest& f = *s_->farm;
  const std::string job = submit("paused", 0, 0);  // 1 tile
  pb::TileLease lease;
  ASSERT_TRUE(f.lease(kWorkerToken, "patient-worker", &lease).ok());
  ASSERT_TRUE(lease.granted());
  std::atomic<bool> done{false};
  std::atomic<int> invalid{0}, valid{0};
  std::thread renewer([&] {
    while (!done) {
      pb::RenewReply r;
      if (f.renew(kWorkerToken, lease.lease_id(), &r).ok()) ++(r.valid() ? valid : invalid);
      std::this_thread::sleep_for(std::chrono::milliseconds(300));
    }
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  ASSERT_EQ(kill(f.pid(), SIGSTOP), 0);
  std::this_thread::sleep_for(std::chrono::seconds(3));
  ASSERT_EQ(kill(f.pid(), SIGCONT), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  done = true;
  renewer.join();
  EXPECT_EQ(invalid.load(), 0) << f.log();
  EXPECT_GE(valid.load(), 3);
  pb::TileLease again;
  ASSERT_TRUE(f.lease(kWorkerToken, "other-worker", &again).ok());
  EXPECT_FALSE(again.granted()) << "the paused lease's tile was handed out again";
  EXPECT_EQ(f.job(job).state(), pb::JOB_RUNNING);
  EXPECT_NE(f.log().find("the coordinator paused or its store unavailable"), std::string::npos) << f.log();
}

// A cancelled job's acknowledged tile results are removed from the data folder (they
// would never be merged), and a later failure of one of its leases does not turn the
// cancellation into a failure.
TEST_F(FarmLeaseRulesTest, CancelledJobLeavesNoTileResultsAndStaysCancelled) {
  FarmUnderTest& f = *s_->farm;
  const std::string job = submit("cancelled-with-results", 32, 0);  // 4 tiles
  pb::TileLease done, pending;
  ASSERT_TRUE(f.lease(kWorkerToken, "cancel-worker", &done).ok());
  ASSERT_TRUE(f.lease(kWorkerToken, "cancel-worker", &pending).ok());
  ASSERT_TRUE(done.granted() && pending.granted());
  pb::CompleteReply reply;
  ASSERT_TRUE(f.complete(kWorkerToken, resultChunks(done.lease_id(), s_->bake(done, done.tile_x(), done.tile_y())), &reply).ok());
  ASSERT_TRUE(reply.accepted());
  const fs::path tiles = f.dataDir() / "tiles" / job;
  ASSERT_TRUE(fs::exists(tiles / (std::to_string(done.tile_index()) + ".cpvt")));

  ASSERT_TRUE(f.cancel(kClientToken, job).ok());
  bool removed = false;
  for (int i = 0; i < 100 && !removed; ++i) {
    removed = !fs::exists(tiles);
    if (!removed) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_TRUE(removed) << tiles << " still exists 5 s after the cancel";
  EXPECT_TRUE(f.fail(kWorkerToken, pending.lease_id(), "late failure").ok());
  pb::JobStatus st = f.job(job);
  EXPECT_EQ(st.state(), pb::JOB_CANCELLED);
  EXPECT_EQ(st.error(), "cancelled");
}

TEST_F(FarmLeaseRulesTest, HigherPriorityJobIsLeasedFirst) {
  FarmUnderTest& f = *s_->farm;
  const std::string low = submit("low", 32, 1);  // 4 tiles each, the low one older
  const std::string high = submit("high", 32, 7);
  std::vector<std::string> leases;
  for (uint64_t t = 0; t < 4; ++t) {
    pb::TileLease l;
    ASSERT_TRUE(f.lease(kWorkerToken, "eager-worker", &l).ok());
    ASSERT_TRUE(l.granted());
    EXPECT_EQ(l.job_id(), high) << "lease " << t;
    EXPECT_EQ(l.tile_index(), t);
    leases.push_back(l.lease_id());
  }
  // Still held (so none of them went back to the queue): the next tile is the low job's.
  for (const auto& id : leases) {
    pb::RenewReply r;
    ASSERT_TRUE(f.renew(kWorkerToken, id, &r).ok());
    ASSERT_TRUE(r.valid());
  }
  pb::TileLease l;
  ASSERT_TRUE(f.lease(kWorkerToken, "eager-worker", &l).ok());
  ASSERT_TRUE(l.granted());
  EXPECT_EQ(l.job_id(), low);
  EXPECT_EQ(f.job(high).state(), pb::JOB_RUNNING);
}

}  // namespace
}  // namespace cpvs
