// The standard gRPC health service (grpc.health.v1.Health/Check) as a client asks it:
// what readiness probes and `cpvs-server --check` read.
#pragma once

#include <string>

#include "cpvs/net/connection.h"

namespace cpvs::net {

/// What the server's health service answers for `service` ("" is the whole server):
/// "SERVING", "NOT_SERVING", "SERVICE_UNKNOWN", or the call's error as text.
std::string healthOf(const Connection& c, const std::string& service = "", double seconds = 5);

}  // namespace cpvs::net
