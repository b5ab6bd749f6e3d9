// Errors of the farm by kind, and their two-way mapping to gRPC statuses: the one place
// where a kind becomes a status code (at a server's edge) and a status code becomes a
// kind again (at a client's). Every kind survives the wire (tests/net/status_test).
#pragma once

#include <grpcpp/support/status.h>

#include <stdexcept>
#include <string>

namespace cpvs::net {

enum class ErrorKind {
  InvalidArgument,     // the request itself is malformed
  NotFound,            // an unknown job, scene or lease
  FailedPrecondition,  // valid, but not now (upload incomplete, job not done)
  AlreadyExists,       // a request id reused for a different job
  ResourceExhausted,   // a quota
  OutOfRange,          // an offset past the end of a file
  DataLoss,            // a transfer that does not match its size or checksum
  Unauthenticated,     // no token, or an unknown one
  PermissionDenied,    // a token whose role may not call this
  Unavailable,         // the other side could not be reached
  DeadlineExceeded,    // the call ran out of time
  Cancelled,           // the caller went away or gave up
  Internal,            // a bug or a local failure (disk full) of the side that reports it
};

/// Every kind, for tests and tables.
inline constexpr ErrorKind kErrorKinds[] = {
    ErrorKind::InvalidArgument, ErrorKind::NotFound,         ErrorKind::FailedPrecondition, ErrorKind::AlreadyExists,
    ErrorKind::ResourceExhausted, ErrorKind::OutOfRange,     ErrorKind::DataLoss,           ErrorKind::Unauthenticated,
    ErrorKind::PermissionDenied, ErrorKind::Unavailable,     ErrorKind::DeadlineExceeded,   ErrorKind::Cancelled,
    ErrorKind::Internal};

/// An error of the farm: a kind and a message for people.
struct FarmError : std::runtime_error {
  FarmError(ErrorKind k, const std::string& message) : std::runtime_error(message), kind(k) {}
  ErrorKind kind;
};

/// The status a server answers with for an error of this kind.
grpc::Status toGrpcStatus(const FarmError& e);
/// The error a client raises for a failed status (`s` not OK): codes without a kind of
/// their own (UNKNOWN, UNIMPLEMENTED, ABORTED) become Internal, their name kept in the message.
FarmError fromGrpcStatus(const grpc::Status& s);

/// "UNAVAILABLE: failed to connect ..." for messages.
std::string describe(const grpc::Status& s);
/// "NOT_FOUND" style name of a kind: the status code it travels as.
const char* errorKindName(ErrorKind kind);

}  // namespace cpvs::net
