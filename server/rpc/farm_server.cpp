#include "rpc/farm_server.h"

#include <spdlog/spdlog.h>

#include <grpcpp/resource_quota.h>

#include <algorithm>
#include <chrono>

#include "cpvs/base/error.h"
#include "cpvs/net/channel.h"

namespace cpvs::server {

FarmServer::FarmServer(Coordinator& coordinator, const TokenTable& tokens, const std::string& listen,
                       std::shared_ptr<grpc::ServerCredentials> creds, AuthLimits authLimits, bool workerCertificates,
                       ConnectionLimits connections)
    : gate_(tokens, authLimits, workerCertificates), farm_(coordinator, gate_), workers_(coordinator, gate_) {
  grpc::EnableDefaultHealthCheckService(true);
  grpc::ServerBuilder builder;
  builder.AddListeningPort(listen, creds ? creds : grpc::InsecureServerCredentials(), &port_);
  // One server per port: gRPC's default SO_REUSEPORT would let a second bind it too (R14).
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  // Clients ping open streams every kKeepaliveMs (net/channel.h); the server pings too,
  // and drops a connection whose peer stopped answering (a partition), which ends its
  // calls and gives back their places.
  const auto ms = [](double seconds) { return int(std::min(seconds * 1000, 2e9)); };
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, ms(connections.keepaliveSeconds));
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, ms(connections.keepaliveTimeoutSeconds));
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, net::kKeepaliveMs / 2);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MAX_PING_STRIKES, 0);
  // Limits at the edge (R15): threads (each open call of this synchronous server holds
  // one; watches are capped below this by the service, so workers get through them),
  // streams per connection, and idle connections closed.
  grpc::ResourceQuota quota("cpvs-server");
  quota.SetMaxThreads(coordinator.config().maxWatches + connections.spareThreads);
  builder.SetResourceQuota(quota);
  builder.AddChannelArgument(GRPC_ARG_MAX_CONCURRENT_STREAMS, connections.streamsPerConnection);
  builder.AddChannelArgument(GRPC_ARG_MAX_CONNECTION_IDLE_MS, ms(connections.idleSeconds));
  builder.SetMaxReceiveMessageSize(net::kMaxMessageBytes);
  builder.SetMaxSendMessageSize(net::kMaxMessageBytes);
  builder.RegisterService(&farm_);
  builder.RegisterService(&workers_);
  server_ = builder.BuildAndStart();
  if (!server_ || port_ == 0) throw InputError("cannot listen on " + listen);
  // The standard health service says NOT_SERVING while the store cannot take a write
  // (held busy, wedged), not SERVING whatever happens (R27); its service "cpvs.leases"
  // says whether leases move (the reaper's rounds), for `cpvs-server --check`.
  server_->GetHealthCheckService()->SetServingStatus(kLeasesHealth, true);
  health_ = std::thread([this, &coordinator] {
    bool serving = true, moving = true;
    std::unique_lock lock(healthMutex_);
    while (!healthStop_) {
      lock.unlock();
      const bool now = coordinator.healthy();
      const bool movingNow = coordinator.leasesMoving();
      lock.lock();
      if (healthStop_) break;
      const bool changed = now != serving || movingNow != moving;
      if (now != serving) {
        serving = now;
        server_->GetHealthCheckService()->SetServingStatus(serving);  // every service's
        spdlog::warn("health: {}", serving ? "SERVING again" : "NOT_SERVING (the job store does not answer)");
      }
      if (movingNow != moving) {
        moving = movingNow;
        spdlog::warn("health: leases {}", moving ? "move again" : "do not move (no reaper round for 10 s)");
      }
      if (changed) server_->GetHealthCheckService()->SetServingStatus(kLeasesHealth, moving);
      healthWake_.wait_for(lock, std::chrono::milliseconds(500), [&] { return healthStop_; });
    }
  });
  address_ = listen.substr(0, listen.rfind(':')) + ":" + std::to_string(port_);
}

FarmServer::~FarmServer() { shutdown(0); }

void FarmServer::shutdown(double graceSeconds) {
  {
    std::lock_guard lock(healthMutex_);
    healthStop_ = true;
  }
  healthWake_.notify_all();
  if (health_.joinable()) health_.join();
  if (!server_) return;
  server_->Shutdown(std::chrono::system_clock::now() +
                    std::chrono::milliseconds(static_cast<int64_t>(graceSeconds * 1000)));
  server_.reset();
}

}  // namespace cpvs::server
