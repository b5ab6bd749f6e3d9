#include "cpvs/net/status.h"

namespace cpvs::net {

namespace {

struct KindCode {
  ErrorKind kind;
  grpc::StatusCode code;
  const char* name;
};

constexpr KindCode kTable[] = {
    {ErrorKind::InvalidArgument, grpc::StatusCode::INVALID_ARGUMENT, "INVALID_ARGUMENT"},
    {ErrorKind::NotFound, grpc::StatusCode::NOT_FOUND, "NOT_FOUND"},
    {ErrorKind::FailedPrecondition, grpc::StatusCode::FAILED_PRECONDITION, "FAILED_PRECONDITION"},
    {ErrorKind::AlreadyExists, grpc::StatusCode::ALREADY_EXISTS, "ALREADY_EXISTS"},
    {ErrorKind::ResourceExhausted, grpc::StatusCode::RESOURCE_EXHAUSTED, "RESOURCE_EXHAUSTED"},
    {ErrorKind::OutOfRange, grpc::StatusCode::OUT_OF_RANGE, "OUT_OF_RANGE"},
    {ErrorKind::DataLoss, grpc::StatusCode::DATA_LOSS, "DATA_LOSS"},
    {ErrorKind::Unauthenticated, grpc::StatusCode::UNAUTHENTICATED, "UNAUTHENTICATED"},
    {ErrorKind::PermissionDenied, grpc::StatusCode::PERMISSION_DENIED, "PERMISSION_DENIED"},
    {ErrorKind::Unavailable, grpc::StatusCode::UNAVAILABLE, "UNAVAILABLE"},
    {ErrorKind::DeadlineExceeded, grpc::StatusCode::DEADLINE_EXCEEDED, "DEADLINE_EXCEEDED"},
    {ErrorKind::Cancelled, grpc::StatusCode::CANCELLED, "CANCELLED"},
    {ErrorKind::Internal, grpc::StatusCode::INTERNAL, "INTERNAL"},
};
static_assert(std::size(kTable) == std::size(kErrorKinds), "every kind has its status code");

const char* codeName(grpc::StatusCode code) {
  static const char* names[] = {"OK", "CANCELLED", "UNKNOWN", "INVALID_ARGUMENT", "DEADLINE_EXCEEDED", "NOT_FOUND",
                                "ALREADY_EXISTS", "PERMISSION_DENIED", "RESOURCE_EXHAUSTED", "FAILED_PRECONDITION",
                                "ABORTED", "OUT_OF_RANGE", "UNIMPLEMENTED", "INTERNAL", "UNAVAILABLE", "DATA_LOSS",
                                "UNAUTHENTICATED"};
  const int c = int(code);
  return c >= 0 && c <= 16 ? names[c] : nullptr;
}

}  // namespace

grpc::Status toGrpcStatus(const FarmError& e) {
  for (const KindCode& k : kTable)
    if (k.kind == e.kind) return grpc::Status(k.code, e.what());
  return grpc::Status(grpc::StatusCode::INTERNAL, e.what());
}

FarmError fromGrpcStatus(const grpc::Status& s) {
  for (const KindCode& k : kTable)
    if (k.code == s.error_code()) return FarmError(k.kind, describe(s));
  return FarmError(ErrorKind::Internal, describe(s));
}

std::string describe(const grpc::Status& s) {
  const char* name = codeName(s.error_code());
  return (name ? std::string(name) : std::to_string(int(s.error_code()))) + ": " + s.error_message();
}

const char* errorKindName(ErrorKind kind) {
  for (const KindCode& k : kTable)
    if (k.kind == kind) return k.name;
  return "INTERNAL";
}

}  // namespace cpvs::net
