// Errors of the coordinator's logic, by kind; the gRPC edge turns each kind into a status.
#pragma once

#include <stdexcept>
#include <string>

namespace cpvs::server {

enum class ErrorKind {
  InvalidArgument,     // the request itself is malformed
  NotFound,            // an unknown job, scene or lease
  FailedPrecondition,  // valid, but not now (upload incomplete, job not done)
  AlreadyExists,       // a request id reused for a different job
  ResourceExhausted,   // a quota
  DataLoss,            // a transfer that does not match its checksum
  Internal,
};

struct FarmError : std::runtime_error {
  FarmError(ErrorKind k, const std::string& message) : std::runtime_error(message), kind(k) {}
  ErrorKind kind;
};

}  // namespace cpvs::server
