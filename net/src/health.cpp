#include "cpvs/net/health.h"

#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>

#include <future>

#include "cpvs/net/channel.h"
#include "cpvs/net/status.h"

namespace cpvs::net {

std::string healthOf(const Connection& c, const std::string& service, double seconds) {
  // The health messages by hand (Debian ships no generated health stubs):
  // HealthCheckRequest{service = 1: string}, HealthCheckResponse{status = 1: enum}.
  if (service.size() > 127) return "a service name of " + std::to_string(service.size()) + " bytes";
  std::string requestBytes;
  if (!service.empty()) requestBytes = std::string("\x0a", 1) + char(service.size()) + service;
  grpc::GenericStub stub(makeChannel(c));
  grpc::ClientContext ctx;
  prepare(ctx, c, seconds);
  // Connection attempts are retried until the deadline: a coordinator slow to shake hands
  // under load is not counted as down on its first attempt.
  ctx.set_wait_for_ready(true);
  grpc::Slice slice(requestBytes);
  grpc::ByteBuffer request(&slice, 1), response;
  std::promise<grpc::Status> done;
  stub.UnaryCall(&ctx, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request, &response,
                 [&](grpc::Status s) { done.set_value(s); });
  const grpc::Status s = done.get_future().get();
  if (s.error_code() == grpc::StatusCode::NOT_FOUND) return "SERVICE_UNKNOWN";
  if (!s.ok()) return describe(s);
  std::vector<grpc::Slice> slices;
  response.Dump(&slices);
  std::string bytes;
  for (const auto& part : slices) bytes.append(reinterpret_cast<const char*>(part.begin()), part.size());
  if (bytes == std::string("\x08\x01", 2)) return "SERVING";
  if (bytes == std::string("\x08\x02", 2)) return "NOT_SERVING";
  if (bytes == std::string("\x08\x03", 2) || bytes.empty()) return "SERVICE_UNKNOWN";  // 0 is UNKNOWN
  return "an unexpected answer of " + std::to_string(bytes.size()) + " bytes";
}

}  // namespace cpvs::net
