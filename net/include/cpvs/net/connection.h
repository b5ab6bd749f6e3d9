// Where the coordinator is and how to talk to it: no transport type, so that libraries
// over the farm (the client library, a runtime) can name it in their headers.
#pragma once

#include <string>

namespace cpvs::net {

struct Connection {
  std::string address;  // HOST:PORT
  std::string token;    // bearer token; empty = none
  std::string caFile;   // PEM roots to trust: TLS when set, plaintext otherwise
  // Send the token in plaintext to an address that is not this machine's (a private
  // network the operator trusts). Without it a token goes over TLS or to loopback only.
  bool allowPlaintextToken = false;
  // The name the server's certificate must hold when it is not the address's host (a
  // coordinator checking itself on 127.0.0.1 with a certificate for its public name).
  std::string tlsName{};
  // A client certificate and its key (PEM) to present over TLS: a worker's own identity
  // for a coordinator with --worker-ca, instead of a token.
  std::string certFile{}, keyFile{};
};

/// Whether HOST:PORT names this machine only: localhost, 127.0.0.0/8, ::1, or a Unix socket.
bool isLoopbackAddress(const std::string& hostPort);

}  // namespace cpvs::net
