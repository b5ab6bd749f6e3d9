// Errors of the farm by kind, and their two-way mapping to gRPC statuses: the one place
// where a kind becomes a status code (at a server's edge) and a status code becomes a
// kind again (at a client's). Every kind survives the wire (tests/net/status_test).
#pragma once

#include <grpcpp/support/status.h>

#include <string>

#include "cpvs/net/error_kind.h"

namespace cpvs::net {

/// The status a server answers with for an error of this kind.
grpc::Status toGrpcStatus(const FarmError& e);
/// The error a client raises for a failed status (`s` not OK): codes without a kind of
/// their own (UNKNOWN, UNIMPLEMENTED, ABORTED) become Internal, their name kept in the message.
FarmError fromGrpcStatus(const grpc::Status& s);

/// "UNAVAILABLE: failed to connect ..." for messages.
std::string describe(const grpc::Status& s);

}  // namespace cpvs::net
