// The coordinator's limits at the gRPC edge (R15), each hit on purpose: streams per
// connection, server threads, idle connections and keepalive of a partitioned peer. Each
// test then sees the coordinator still serving.
#include <gtest/gtest.h>
#include <grpcpp/grpcpp.h>

#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "cpvs/net/channel.h"
#include "cpvs/net/status.h"
#include "farm_testing.h"
#include "partition_proxy.h"

namespace cpvs {
namespace {

namespace pb = ::cpvs::v1;
using testing::InProcessFarm;
using testing::TempDir;
using Clock = std::chrono::steady_clock;

/// A channel of its own (its own TCP connection) to `address`.
std::shared_ptr<grpc::Channel> ownChannel(const std::string& address, int tag) {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  args.SetInt("cpvs.test.channel", tag);
  return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
}

/// Streaming calls started asynchronously on one completion queue, each followed until
/// its first message or its end: what a test counts.
template <typename Reply>
class OpenStreams {
 public:
  struct Call {
    grpc::ClientContext ctx;
    std::unique_ptr<grpc::ClientAsyncReader<Reply>> reader;
    Reply first;
    grpc::Status status;
    bool answered = false, finished = false;
  };

  /// Starts a call made by `prepare(ctx, cq)`.
  template <typename Prepare>
  void start(Prepare prepare) {
    calls_.push_back(std::make_unique<Call>());
    Call& c = *calls_.back();
    c.reader = prepare(&c.ctx, &cq_);
    c.reader->StartCall(tag(calls_.size() - 1, 0));
  }

  /// Follows events until `done()` or `seconds` pass.
  template <typename Done>
  void follow(double seconds, Done done) {
    const auto deadline = std::chrono::system_clock::now() + std::chrono::duration_cast<std::chrono::milliseconds>(
                                                                  std::chrono::duration<double>(seconds));
    while (!done()) {
      void* t;
      bool ok;
      if (cq_.AsyncNext(&t, &ok, deadline) != grpc::CompletionQueue::GOT_EVENT) return;
      handle(t, ok);
    }
  }

  int answered() const { return count([](const Call& c) { return c.answered && !c.finished; }); }
  int finishedWith(grpc::StatusCode code) const {
    return count([code](const Call& c) { return c.finished && c.status.error_code() == code; });
  }
  int finished() const { return count([](const Call& c) { return c.finished; }); }
  Call& operator[](size_t i) { return *calls_[i]; }
  size_t size() const { return calls_.size(); }

  ~OpenStreams() {
    for (auto& c : calls_) c->ctx.TryCancel();
    follow(10, [&] { return finished() == int(calls_.size()); });
    cq_.Shutdown();
    void* t;
    bool ok;
    while (cq_.Next(&t, &ok)) {
    }
  }

 private:
  static void* tag(size_t i, int phase) { return reinterpret_cast<void*>(intptr_t(i) * 4 + phase); }
  void handle(void* t, bool ok) {
    const size_t i = size_t(reinterpret_cast<intptr_t>(t) / 4);
    const int phase = int(reinterpret_cast<intptr_t>(t) % 4);
    Call& c = *calls_[i];
    if (phase == 0 && ok) {
      c.reader->Read(&c.first, tag(i, 1));
    } else if (phase == 1 && ok) {
      c.answered = true;
      c.reader->Read(&c.first, tag(i, 1));  // keep reading: the end shows up too
    } else if (phase <= 1) {
      c.reader->Finish(&c.status, tag(i, 2));
    } else {
      c.finished = true;
    }
  }
  template <typename F>
  int count(F f) const {
    int n = 0;
    for (const auto& c : calls_) n += f(*c) ? 1 : 0;
    return n;
  }

  grpc::CompletionQueue cq_;
  std::vector<std::unique_ptr<Call>> calls_;
};

/// A farm with one job that stays queued (no worker), for watches to follow.
struct WatchedFarm {
  WatchedFarm(const std::string& name, server::CoordinatorConfig config, server::ConnectionLimits limits)
      : dir(name), farm((config.dataDir = dir / "data", config), limits) {
    jobId = farm.client.submit(name, farm.uploadAndSpec(dir / "box.obj", "city:1:1", "64")).jobId;
  }
  /// Starts a watch of the job on `stub`.
  void watch(OpenStreams<pb::JobStatus>& streams, pb::Farm::Stub& stub) const {
    pb::JobRef ref;
    ref.set_job_id(jobId);
    streams.start([&](grpc::ClientContext* ctx, grpc::CompletionQueue* cq) {
      ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
      return stub.PrepareAsyncWatchJob(ctx, ref, cq);
    });
  }
  /// Whether a unary call (the job list) is answered within 10 s.
  bool answers() const {
    auto stub = pb::Farm::NewStub(ownChannel(farm.server.address(), 9999));
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
    pb::ListJobsRequest req;
    pb::ListJobsReply reply;
    return stub->ListJobs(&ctx, req, &reply).ok() && reply.jobs_size() == 1;
  }

  TempDir dir;
  InProcessFarm farm;
  std::string jobId;
};

// Past --max-streams-per-connection, further calls on that connection wait (HTTP/2's
// SETTINGS_MAX_CONCURRENT_STREAMS) until one ends; other connections are not held up.
TEST(EdgeLimits, StreamsPastTheLimitOfAConnectionWaitForAPlace) {
  server::ConnectionLimits limits;
  limits.streamsPerConnection = 4;
  WatchedFarm f("cpvs_edge_streams", {}, limits);
  auto one = pb::Farm::NewStub(ownChannel(f.farm.server.address(), 1));
  OpenStreams<pb::JobStatus> streams;
  for (int i = 0; i < 6; ++i) f.watch(streams, *one);
  streams.follow(10, [&] { return streams.answered() == 4; });
  streams.follow(1, [] { return false; });  // a second for the others to show, were they served
  EXPECT_EQ(streams.answered(), 4);
  EXPECT_EQ(streams.finished(), 0) << "the others wait, not refused";
  // Another connection gets its watch at once.
  auto other = pb::Farm::NewStub(ownChannel(f.farm.server.address(), 2));
  f.watch(streams, *other);
  streams.follow(10, [&] { return streams.answered() == 5; });
  EXPECT_EQ(streams.answered(), 5);
  // Two places given back on the first connection: the two waiting get them.
  streams[0].ctx.TryCancel();
  streams[1].ctx.TryCancel();
  streams.follow(10, [&] { return streams.finished() == 2 && streams.answered() == 5; });
  EXPECT_EQ(streams.finishedWith(grpc::StatusCode::CANCELLED), 2);
  EXPECT_EQ(streams.answered(), 5);  // 2 of the first 4, the 2 that waited, the other connection's
  EXPECT_TRUE(streams[4].answered && streams[5].answered);
  EXPECT_TRUE(f.answers());
}

// Every open call of the synchronous server holds a thread: past the watches' cap plus
// the spare threads, calls are refused with RESOURCE_EXHAUSTED instead of starting
// threads without bound; once they end, calls are served again.
TEST(EdgeLimits, ServerThreadsHaveACeiling) {
  server::CoordinatorConfig config;
  config.maxWatches = 2;
  server::ConnectionLimits limits;
  limits.spareThreads = 16;
  WatchedFarm f("cpvs_edge_threads", config, limits);
  // Upload streams that send nothing hold their thread while they wait for a first chunk.
  auto stub = pb::Farm::NewStub(ownChannel(f.farm.server.address(), 1));
  std::vector<std::unique_ptr<grpc::ClientAsyncWriter<pb::UploadSceneChunk>>> writers;
  std::vector<std::unique_ptr<grpc::ClientContext>> contexts;
  std::vector<grpc::Status> statuses(60);
  std::vector<pb::UploadSceneReply> replies(60);
  grpc::CompletionQueue cq;
  for (size_t i = 0; i < 60; ++i) {
    contexts.push_back(std::make_unique<grpc::ClientContext>());
    contexts.back()->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
    writers.push_back(stub->PrepareAsyncUploadScene(contexts.back().get(), &replies[i], &cq));
    writers.back()->StartCall(reinterpret_cast<void*>(i * 4));
  }
  // The refused ones end; the held ones stay open.
  int refused = 0, otherEnd = 0;
  const auto deadline = std::chrono::system_clock::now() + std::chrono::seconds(5);
  for (;;) {
    void* t;
    bool ok;
    if (cq.AsyncNext(&t, &ok, deadline) != grpc::CompletionQueue::GOT_EVENT) break;
    const size_t i = size_t(reinterpret_cast<intptr_t>(t) / 4);
    const int phase = int(reinterpret_cast<intptr_t>(t) % 4);
    if (phase == 0) {
      // Started: a refused call answers at once (with its status alone); a held one sends
      // nothing while it waits for a chunk.
      writers[i]->ReadInitialMetadata(reinterpret_cast<void*>(i * 4 + 1));
    } else if (phase == 1) {
      writers[i]->Finish(&statuses[i], reinterpret_cast<void*>(i * 4 + 2));
    } else {
      ++(statuses[i].error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED ? refused : otherEnd);
    }
  }
  EXPECT_GT(refused, 0) << "60 held calls against a ceiling of 18 threads";
  EXPECT_EQ(otherEnd, 0);
  EXPECT_GE(60 - refused, 8) << "the calls under the ceiling were served";
  EXPECT_LE(60 - refused, 2 + 16);
  // Once they end, the coordinator answers again.
  for (auto& c : contexts) c->TryCancel();
  const auto drain = std::chrono::system_clock::now() + std::chrono::seconds(10);
  for (int left = 60 - refused - otherEnd; left > 0;) {
    void* t;
    bool ok;
    if (cq.AsyncNext(&t, &ok, drain) != grpc::CompletionQueue::GOT_EVENT) break;
    const size_t i = size_t(reinterpret_cast<intptr_t>(t) / 4);
    const int phase = int(reinterpret_cast<intptr_t>(t) % 4);
    if (phase == 1) writers[i]->Finish(&statuses[i], reinterpret_cast<void*>(i * 4 + 2));
    left -= phase == 2;
  }
  cq.Shutdown();
  void* t;
  bool ok;
  while (cq.Next(&t, &ok)) {
  }
  bool served = false;
  for (int i = 0; i < 50 && !served; ++i) {
    served = f.answers();
    if (!served) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_TRUE(served);
}

// A connection with no call open for --idle-connection-seconds is closed by the server;
// the client's next call connects again.
TEST(EdgeLimits, IdleConnectionsAreClosed) {
  server::ConnectionLimits limits;
  limits.idleSeconds = 1;
  WatchedFarm f("cpvs_edge_idle", {}, limits);
  auto channel = ownChannel(f.farm.server.address(), 1);
  auto stub = pb::Farm::NewStub(channel);
  auto list = [&] {
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
    pb::ListJobsReply reply;
    return stub->ListJobs(&ctx, pb::ListJobsRequest(), &reply).ok();
  };
  ASSERT_TRUE(list());
  EXPECT_EQ(channel->GetState(false), GRPC_CHANNEL_READY);
  const auto start = Clock::now();
  while (channel->GetState(false) == GRPC_CHANNEL_READY && Clock::now() - start < std::chrono::seconds(10))
    channel->WaitForStateChange(GRPC_CHANNEL_READY, std::chrono::system_clock::now() + std::chrono::milliseconds(200));
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  EXPECT_NE(channel->GetState(false), GRPC_CHANNEL_READY) << "still connected after " << seconds << " s";
  EXPECT_GE(seconds, 0.5);
  EXPECT_TRUE(list()) << "the next call connects again";
}

// A watcher behind a partition (its connection carries nothing more, no FIN, no RST)
// held a watch place for good. The server's keepalive pings go unanswered, it closes the
// connection, the watch ends and its place is given back.
TEST(EdgeLimits, APartitionedWatcherGivesItsPlaceBack) {
  server::CoordinatorConfig config;
  config.maxWatches = 1;
  server::ConnectionLimits limits;
  limits.keepaliveSeconds = 1;
  limits.keepaliveTimeoutSeconds = 1;
  WatchedFarm f("cpvs_edge_keepalive", config, limits);
  testing::PartitionProxy proxy(f.farm.server.address());
  auto behind = pb::Farm::NewStub(ownChannel(proxy.address(), 1));
  auto direct = pb::Farm::NewStub(ownChannel(f.farm.server.address(), 2));
  OpenStreams<pb::JobStatus> streams;
  f.watch(streams, *behind);
  streams.follow(10, [&] { return streams.answered() == 1; });
  ASSERT_EQ(streams.answered(), 1);
  f.watch(streams, *direct);  // the one place is taken
  streams.follow(10, [&] { return streams.finished() == 1; });
  EXPECT_EQ(streams.finishedWith(grpc::StatusCode::RESOURCE_EXHAUSTED), 1);
  proxy.cutOpenConnections();
  const auto cut = Clock::now();
  // A direct watch every half second until one is taken.
  bool taken = false;
  while (!taken && Clock::now() - cut < std::chrono::seconds(20)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    const size_t at = streams.size();
    f.watch(streams, *direct);
    streams.follow(10, [&] { return streams[at].answered || streams[at].finished; });
    taken = streams[at].answered;
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - cut).count();
  EXPECT_TRUE(taken) << "the place was not given back in 20 s";
  EXPECT_LT(seconds, 10) << "keepalive 1 s + timeout 1 s";
  std::printf("the partitioned watch's place came back %.1f s after the cut\n", seconds);
  EXPECT_TRUE(f.answers());
}

}  // namespace
}  // namespace cpvs
