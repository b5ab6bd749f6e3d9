// Every error kind survives the wire: a server in this process (port 0) answers with the
// status of each kind, and the client turns the status it receives back into that kind
// and message. And the chunked receiver's rules, case by case.
#include <gtest/gtest.h>
#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

#include "cpvs/net/channel.h"
#include "cpvs/net/chunked_stream.h"
#include "cpvs/net/status.h"
#include "cpvs/v1/farm.grpc.pb.h"

namespace cpvs::net {
namespace {

namespace pb = ::cpvs::v1;

// Answers GetUploadStatus with the error whose kind is the index in scene_hash.
class FailingFarm final : public pb::Farm::Service {
 public:
  grpc::Status GetUploadStatus(grpc::ServerContext*, const pb::SceneRef* req, pb::UploadStatus*) override {
    const ErrorKind kind = kErrorKinds[std::stoi(req->scene_hash())];
    return toGrpcStatus(FarmError(kind, std::string("because of ") + errorKindName(kind)));
  }
};

TEST(ErrorKinds, EveryKindSurvivesTheWire) {
  FailingFarm service;
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&service);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  ASSERT_TRUE(server);
  ASSERT_GT(port, 0);
  auto stub = pb::Farm::NewStub(makeChannel(Connection{"127.0.0.1:" + std::to_string(port), "", ""}));
  for (size_t i = 0; i < std::size(kErrorKinds); ++i) {
    grpc::ClientContext ctx;
    prepare(ctx, Connection{}, 10);
    pb::SceneRef ref;
    ref.set_scene_hash(std::to_string(i));
    pb::UploadStatus out;
    const grpc::Status s = stub->GetUploadStatus(&ctx, ref, &out);
    ASSERT_FALSE(s.ok());
    const FarmError back = fromGrpcStatus(s);
    const char* name = errorKindName(kErrorKinds[i]);
    EXPECT_EQ(back.kind, kErrorKinds[i]) << name;
    EXPECT_EQ(std::string(back.what()), std::string(name) + ": because of " + name);
  }
  server->Shutdown();
}

TEST(ErrorKinds, CodesWithoutAKindAreInternalAndKeepTheirName) {
  const FarmError e = fromGrpcStatus(grpc::Status(grpc::StatusCode::UNIMPLEMENTED, "no such call"));
  EXPECT_EQ(e.kind, ErrorKind::Internal);
  EXPECT_STREQ(e.what(), "UNIMPLEMENTED: no such call");
}

std::string ruleBroken(auto steps) {
  try {
    steps();
  } catch (const FarmError& e) {
    EXPECT_EQ(e.kind, ErrorKind::InvalidArgument);
    return e.what();
  }
  return "";
}

TEST(ChunkReceiver, EveryRuleOfAStream) {
  auto receiver = [](uint64_t offset = 0) { return ChunkReceiver(offset, 100, ErrorKind::InvalidArgument, "x"); };
  ChunkReceiver ok = receiver(10);
  EXPECT_EQ(ok.accept(30, 10, 15), 10u);
  EXPECT_EQ(ok.accept(std::nullopt, std::nullopt, 5), 25u);
  EXPECT_NO_THROW(ok.finish());
  EXPECT_EQ(ok.total(), 30u);
  EXPECT_NE(ruleBroken([&] { receiver().accept(101, 0, 1); }).find("over the limit"), std::string::npos);
  EXPECT_NE(ruleBroken([&] { receiver(20).accept(10, 20, 0); }).find("less than"), std::string::npos);
  EXPECT_NE(ruleBroken([&] { receiver().accept(std::nullopt, 0, 1); }).find("announces no size"), std::string::npos);
  EXPECT_NE(ruleBroken([&] {
              auto r = receiver();
              r.accept(50, 0, 10);
              r.accept(60, 10, 10);
            }).find("size changed"),
            std::string::npos);
  EXPECT_NE(ruleBroken([&] {
              auto r = receiver();
              r.accept(50, 0, 10);
              r.accept(50, 5, 10);
            }).find("at byte 5 where byte 10"),
            std::string::npos);
  EXPECT_NE(ruleBroken([&] { receiver().accept(50, 0, 51); }).find("runs past"), std::string::npos);
  EXPECT_NE(ruleBroken([&] {
              ChunkReceiver r(0, uint64_t(1) << 40, ErrorKind::InvalidArgument, "x");
              r.accept(uint64_t(1) << 30, 0, kChunkBytes + 1);
            }).find("the limit is"),
            std::string::npos);
  EXPECT_NE(ruleBroken([&] {
              auto r = receiver();
              r.accept(50, 0, 10);
              r.finish();
            }).find("truncated: 10 of 50"),
            std::string::npos);
}

// What the sender emits: consecutive chunks, the first marked, at least one message.
struct Recorder {
  std::vector<std::pair<uint64_t, std::string>> chunks;
  bool Write(const pb::ArtifactChunk& m) {
    chunks.emplace_back(m.offset(), m.data());
    return true;
  }
};

TEST(SendChunks, ConsecutiveChunksAndOneMessageForNothing) {
  std::string data(kChunkBytes * 2 + 5, 'a');
  for (size_t i = 0; i < data.size(); ++i) data[i] = char('a' + i % 26);
  Recorder r;
  int firsts = 0;
  ASSERT_TRUE(sendChunks<pb::ArtifactChunk>(ChunkSource::ofBytes(data.data(), data.size()), 3, r,
                                            [&](pb::ArtifactChunk& m, uint64_t at, bool first) {
                                              m.set_offset(at);
                                              firsts += first;
                                            }));
  ASSERT_EQ(r.chunks.size(), 3u);
  EXPECT_EQ(firsts, 1);
  std::string joined;
  for (const auto& [at, bytes] : r.chunks) {
    EXPECT_EQ(at, 3 + joined.size());
    joined += bytes;
  }
  EXPECT_EQ(joined, data.substr(3));
  Recorder none;
  ASSERT_TRUE(sendChunks<pb::ArtifactChunk>(ChunkSource::ofBytes(data.data(), 0), 0, none,
                                            [](pb::ArtifactChunk&, uint64_t, bool) {}));
  EXPECT_EQ(none.chunks.size(), 1u);
  EXPECT_THROW(sendChunks<pb::ArtifactChunk>(ChunkSource::ofBytes(data.data(), 4), 5, none,
                                             [](pb::ArtifactChunk&, uint64_t, bool) {}),
               FarmError);
}

}  // namespace
}  // namespace cpvs::net
