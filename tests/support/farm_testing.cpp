#include "farm_testing.h"

#include <unistd.h>

#include "cpvs/net/channel.h"
#include "cpvs/net/convert.h"
#include "cpvs/net/status.h"
#include "cpvs/scene/obj_writer.h"
#include "cpvs/scene/source.h"

namespace cpvs::testing {

namespace fs = std::filesystem;

TempDir::TempDir(const std::string& name) : path_(fs::temp_directory_path() / (name + "_" + std::to_string(::getpid()))) {
  fs::remove_all(path_);
  fs::create_directories(path_);
}

TempDir::~TempDir() {
  std::error_code ignored;
  fs::remove_all(path_, ignored);
}

namespace {

server::CoordinatorConfig defaults(const std::string& dataDir) {
  server::CoordinatorConfig config;
  config.dataDir = dataDir;
  return config;
}

}  // namespace

InProcessFarm::InProcessFarm(server::CoordinatorConfig config, server::ConnectionLimits connections)
    : coordinator(std::move(config)),
      server(coordinator, tokens, "127.0.0.1:0", nullptr, {}, false, connections),
      client(net::Connection{server.address(), "", ""}) {}

InProcessFarm::InProcessFarm(const std::string& dataDir) : InProcessFarm(defaults(dataDir)) {}

net::BakeSpec InProcessFarm::uploadAndSpec(const std::string& objPath, const std::string& scene,
                                           const std::string& resolution, const Vec3& sun) {
  writeObj(objPath, openScene(scene));
  net::BakeSpec spec;
  spec.sceneHash = client.uploadScene(objPath).sceneHash;
  spec.sun = sun;
  spec.resolution = resolution;
  return spec;
}

pb::JobStatus InProcessFarm::submitMessage(const std::string& requestId, const pb::BakeSpec& spec) {
  auto stub = pb::Farm::NewStub(net::makeChannel(connection()));
  pb::SubmitBakeRequest request;
  request.set_request_id(requestId);
  *request.mutable_spec() = spec;
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
  pb::JobStatus out;
  const grpc::Status status = stub->SubmitBake(&ctx, request, &out);
  if (!status.ok()) throw client::FarmCallError(net::fromGrpcStatus(status));
  return out;
}

worker::WorkerConfig workerConfig(const net::Connection& connection, const std::string& cacheDir, int maxTiles) {
  worker::WorkerConfig wc;
  wc.server = connection;
  wc.cacheDir = cacheDir;
  fs::create_directories(cacheDir);
  wc.workerId = "w";
  wc.maxTiles = maxTiles;
  return wc;
}

ServiceServer::ServiceServer(grpc::Service& service) {
  grpc::ServerBuilder builder;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port_);
  builder.RegisterService(&service);
  server_ = builder.BuildAndStart();
}

ServiceServer::~ServiceServer() {
  // Every handler returned, and the server's threads done, before the service (the
  // test's, often a local) can go.
  if (!server_) return;
  server_->Shutdown();
  server_->Wait();
}

ForwardingWorkers::ForwardingWorkers(const std::string& address)
    : stub_(pb::Workers::NewStub(net::makeChannel({address, "", ""}))) {}

grpc::Status ForwardingWorkers::LeaseTile(grpc::ServerContext*, const pb::LeaseRequest* req, pb::TileLease* out) {
  grpc::ClientContext ctx;
  return stub_->LeaseTile(&ctx, *req, out);
}

grpc::Status ForwardingWorkers::RenewLease(grpc::ServerContext*, const pb::RenewRequest* req, pb::RenewReply* out) {
  grpc::ClientContext ctx;
  return stub_->RenewLease(&ctx, *req, out);
}

grpc::Status ForwardingWorkers::FailTile(grpc::ServerContext*, const pb::FailRequest* req, pb::FailReply* out) {
  grpc::ClientContext ctx;
  return stub_->FailTile(&ctx, *req, out);
}

grpc::Status ForwardingWorkers::FetchScene(grpc::ServerContext*, const pb::FetchSceneRequest* req,
                                           grpc::ServerWriter<pb::SceneChunk>* writer) {
  grpc::ClientContext ctx;
  auto reader = stub_->FetchScene(&ctx, *req);
  pb::SceneChunk chunk;
  while (reader->Read(&chunk)) writer->Write(chunk);
  return reader->Finish();
}

grpc::Status ForwardingWorkers::CompleteTile(grpc::ServerContext*, grpc::ServerReader<pb::TileResultChunk>* reader,
                                             pb::CompleteReply* out) {
  std::vector<pb::TileResultChunk> chunks;
  pb::TileResultChunk chunk;
  while (reader->Read(&chunk)) chunks.push_back(chunk);
  return forwardResult(chunks, out);
}

grpc::Status ForwardingWorkers::forwardResult(const std::vector<pb::TileResultChunk>& chunks, pb::CompleteReply* out) {
  grpc::ClientContext ctx;
  auto writer = stub_->CompleteTile(&ctx, out);
  for (const auto& c : chunks) writer->Write(c);
  writer->WritesDone();
  return writer->Finish();
}

}  // namespace cpvs::testing
