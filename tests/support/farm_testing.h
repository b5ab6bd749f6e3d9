// Helpers for tests that run the farm inside the test process: a temporary folder, a
// coordinator served on port 0 with a client of it, a gRPC server for a test's own
// service, and a Workers service that forwards to a coordinator so that a test can
// change what passes between a worker and it.
#pragma once

#include <grpcpp/grpcpp.h>

#include <filesystem>
#include <memory>
#include <string>

#include "coordinator/coordinator.h"
#include "cpvs/base/vec3.h"
#include "cpvs/client/farm_client.h"
#include "cpvs/net/connection.h"
#include "cpvs/v1/farm.grpc.pb.h"
#include "rpc/auth.h"
#include "rpc/farm_server.h"
#include "tile_worker.h"

namespace cpvs::testing {

namespace pb = ::cpvs::v1;

/// A fresh folder under the system's temporary folder, named after `name` and the
/// process, removed with everything in it when this goes out of scope.
class TempDir {
 public:
  explicit TempDir(const std::string& name);
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  /// The path of `relative` inside the folder.
  std::string operator/(const std::string& relative) const { return (path_ / relative).string(); }

 private:
  std::filesystem::path path_;
};

/// A coordinator on `config.dataDir`, served without tokens on 127.0.0.1:0, and a client.
struct InProcessFarm {
  explicit InProcessFarm(server::CoordinatorConfig config, server::ConnectionLimits connections = {});
  /// The same with defaults over `dataDir`.
  explicit InProcessFarm(const std::string& dataDir);

  net::Connection connection() const { return {server.address(), "", ""}; }
  /// Writes the generated scene `spec` ("city:1:1") as OBJ at `objPath`, uploads it, and
  /// returns a bake of it at `resolution` under `sun`.
  net::BakeSpec uploadAndSpec(const std::string& objPath, const std::string& scene, const std::string& resolution,
                              const Vec3& sun = {0.2, -1, 0.1});
  /// Submits `spec` as it is, past the client library's model: for what the coordinator
  /// must refuse that the model cannot even hold (a spot light without a direction).
  /// Throws client::FarmCallError as FarmClient::submit does.
  pb::JobStatus submitMessage(const std::string& requestId, const pb::BakeSpec& spec);

  server::Coordinator coordinator;
  server::TokenTable tokens;
  server::FarmServer server;
  client::FarmClient client;
};

/// A worker of `connection` caching in `cacheDir` (created), with `maxTiles` (0: until stopped).
worker::WorkerConfig workerConfig(const net::Connection& connection, const std::string& cacheDir, int maxTiles = 0);

/// A gRPC server on 127.0.0.1:0 for a test's own service; shut down when destroyed.
class ServiceServer {
 public:
  explicit ServiceServer(grpc::Service& service);
  ~ServiceServer();
  net::Connection connection() const { return {"127.0.0.1:" + std::to_string(port_), "", ""}; }

 private:
  int port_ = 0;
  std::unique_ptr<grpc::Server> server_;
};

/// Forwards every Workers call to the coordinator at `address`; a test overrides what it
/// wants to change or count.
class ForwardingWorkers : public pb::Workers::Service {
 public:
  explicit ForwardingWorkers(const std::string& address);

  grpc::Status LeaseTile(grpc::ServerContext*, const pb::LeaseRequest* req, pb::TileLease* out) override;
  grpc::Status RenewLease(grpc::ServerContext*, const pb::RenewRequest* req, pb::RenewReply* out) override;
  grpc::Status FailTile(grpc::ServerContext*, const pb::FailRequest* req, pb::FailReply* out) override;
  grpc::Status FetchScene(grpc::ServerContext*, const pb::FetchSceneRequest* req,
                          grpc::ServerWriter<pb::SceneChunk>* writer) override;
  grpc::Status CompleteTile(grpc::ServerContext*, grpc::ServerReader<pb::TileResultChunk>* reader,
                            pb::CompleteReply* out) override;

 protected:
  /// Sends a whole result on to the coordinator.
  grpc::Status forwardResult(const std::vector<pb::TileResultChunk>& chunks, pb::CompleteReply* out);
  std::unique_ptr<pb::Workers::Stub> stub_;
};

}  // namespace cpvs::testing
