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
#include "cpvs/net/channel.h"
#include "rpc/auth.h"
#include "rpc/farm_service.h"

namespace cpvs::server {

/// The health service's name for "leases move" (the whole server's "" is the store).
constexpr const char* kLeasesHealth = "cpvs.leases";

/// Limits on connections at the edge (R15), besides the coordinator's own (watches,
/// uploads, jobs).
struct ConnectionLimits {
  int streamsPerConnection = 128;  // calls open at once on one connection (more wait for a place)
  double idleSeconds = 600;        // a connection with no call open this long is closed
  double keepaliveSeconds = net::kKeepaliveMs / 1000.0;  // a connection with calls open is pinged this often...
  double keepaliveTimeoutSeconds = net::kKeepaliveTimeoutMs / 1000.0;  // ...and closed, its calls ended, when
                                                                       // no answer comes this long
  int spareThreads = 256;  // server threads beyond the watches' (each open call holds one)
};

class FarmServer {
 public:
  /// Serves `coordinator` on `listen` (HOST:PORT; port 0 picks a free one) with `creds`
  /// (plaintext when null). InputError when it cannot listen there.
  FarmServer(Coordinator& coordinator, const TokenTable& tokens, const std::string& listen,
             std::shared_ptr<grpc::ServerCredentials> creds = nullptr, AuthLimits authLimits = {},
             bool workerCertificates = false, ConnectionLimits connections = {});
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
