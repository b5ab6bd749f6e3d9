// Who may call: the bearer tokens or a worker's client certificate, and a limit on failed
// authentications per peer address
// (R18). A peer that fails `limit` times within `windowSeconds` is refused every call,
// whatever it sends, for `lockoutSeconds`: guessing tokens costs a guesser that long a
// batch, and the log shows one line per lockout rather than one per guess.
#pragma once

#include <chrono>
#include <map>
#include <mutex>
#include <string>

#include <grpcpp/grpcpp.h>

#include "coordinator/access.h"
#include "rpc/auth.h"

namespace cpvs::server {

struct AuthLimits {
  int limit = 20;              // failed authentications of one address...
  double windowSeconds = 60;   // ...within this long...
  double lockoutSeconds = 60;  // ...lock it out this long (0 limit: never)
};

/// The host of a gRPC peer ("ipv4:10.0.0.7:51234" -> "10.0.0.7", "ipv6:[::1]:5" -> "::1");
/// the whole text for another kind (a Unix socket).
std::string peerHost(const std::string& peer);

class Gatekeeper {
 public:
  /// `workerCertificates`: a caller without a bearer token that presented a client
  /// certificate the TLS handshake verified (against --worker-ca) is a worker, named by
  /// the certificate's common name.
  Gatekeeper(const TokenTable& tokens, AuthLimits limits = {}, bool workerCertificates = false)
      : tokens_(tokens), limits_(limits), workerCertificates_(workerCertificates) {}

  /// Checks the caller's bearer token against the role an RPC needs, and says in `access`
  /// which jobs and tracks the caller may see (R28). RESOURCE_EXHAUSTED while the
  /// caller's address is locked out.
  grpc::Status admit(const grpc::ServerContext* ctx, Role needed, Access* access);

  /// Seconds the address is still locked out for (0: it may call).
  double lockedFor(const std::string& host);
  /// Notes a failed authentication of `host`; true when it locked the address out.
  bool failed(const std::string& host);

 private:
  struct Peer {
    int failures = 0;
    std::chrono::steady_clock::time_point windowStart{}, lockedUntil{};
  };
  const TokenTable& tokens_;
  AuthLimits limits_;
  bool workerCertificates_;
  std::mutex mutex_;
  std::map<std::string, Peer> peers_;  // bounded: cut when it grows past 10,000 addresses
};

}  // namespace cpvs::server
