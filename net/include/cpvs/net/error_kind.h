// The kinds of error of the farm, free of any transport type: what a client library's
// users see. net/status.h maps them to and from gRPC statuses.
#pragma once

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

/// "NOT_FOUND" style name of a kind: the status code it travels as.
const char* errorKindName(ErrorKind kind);

}  // namespace cpvs::net
