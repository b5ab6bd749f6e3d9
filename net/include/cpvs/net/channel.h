// How a client or worker reaches the coordinator: address, bearer token, TLS trust, and
// the message limits both ends agree on.
#pragma once

#include <grpcpp/grpcpp.h>

#include "cpvs/net/connection.h"

#include <memory>
#include <string>

namespace cpvs::net {

/// Chunk size of every streamed transfer (scenes, sub-DAGs, artifacts).
constexpr size_t kChunkBytes = 1 << 20;
/// Largest message either side accepts: a chunk plus its envelope.
constexpr int kMaxMessageBytes = int(kChunkBytes) + (64 << 10);
/// Keepalive pings on long-lived streams (WatchJob, Subscribe): a client pings every
/// kKeepaliveMs while a call is open and gives up after kKeepaliveTimeoutMs without an
/// answer; the server accepts pings that often (gRPC's default refuses pings under 5
/// minutes apart and closes the connection after two).
constexpr int kKeepaliveMs = 30000, kKeepaliveTimeoutMs = 10000;

/// A channel to the coordinator (proxies ignored: farms run on private networks).
/// Throws InputError when the CA file cannot be read.
std::shared_ptr<grpc::Channel> makeChannel(const Connection& c);

/// Adds the bearer token, and a deadline `seconds` from now when > 0.
void prepare(grpc::ClientContext& ctx, const Connection& c, double seconds = 0);

}  // namespace cpvs::net
