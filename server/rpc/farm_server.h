// The coordinator served over gRPC: both services on one port, with the message limits
// and the health service. What cpvs-server runs, and what in-process tests start on
// port 0 (Arrow Flight's pattern).
#pragma once

#include <condition_variable>
#include <mutex>
#include <thread>

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

#include "coordinator/coordinator.h"
#include "rpc/auth.h"
#include "rpc/farm_service.h"

namespace cpvs::server {

/// The health service's name for "leases move" (the whole server's "" is the store).
constexpr const char* kLeasesHealth = "cpvs.leases";

class FarmServer {
 public:
  /// Serves `coordinator` on `listen` (HOST:PORT; port 0 picks a free one) with `creds`
  /// (plaintext when null). InputError when it cannot listen there.
  FarmServer(Coordinator& coordinator, const TokenTable& tokens, const std::string& listen,
             std::shared_ptr<grpc::ServerCredentials> creds = nullptr, AuthLimits authLimits = {},
             bool workerCertificates = false);
  ~FarmServer();
  FarmServer(const FarmServer&) = delete;
  FarmServer& operator=(const FarmServer&) = delete;

  /// The port bound, and HOST:PORT with the host of `listen`.
  int port() const { return port_; }
  const std::string& address() const { return address_; }

  /// Stops accepting calls and ends those in flight after `graceSeconds`.
  void shutdown(double graceSeconds = 5);

 private:
  Gatekeeper gate_;
  FarmService farm_;
  WorkerService workers_;
  std::unique_ptr<grpc::Server> server_;
  int port_ = 0;
  // Sets the health service's status from the coordinator's every half second.
  std::thread health_;
  std::mutex healthMutex_;
  std::condition_variable healthWake_;
  bool healthStop_ = false;
  std::string address_;
};

}  // namespace cpvs::server
