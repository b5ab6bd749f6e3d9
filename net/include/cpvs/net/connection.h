// Where the coordinator is and how to talk to it: no transport type, so that libraries
// over the farm (the client library, a runtime) can name it in their headers.
#pragma once

#include <string>

namespace cpvs::net {

struct Connection {
  std::string address;  // HOST:PORT
  std::string token;    // bearer token; empty = none
  std::string caFile;   // PEM roots to trust: TLS when set, plaintext otherwise
};

}  // namespace cpvs::net
