#include "cpvs/net/channel.h"

#include <chrono>
#include <fstream>
#include <sstream>

#include "cpvs/base/error.h"

namespace cpvs::net {

std::shared_ptr<grpc::Channel> makeChannel(const Connection& c) {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_ENABLE_HTTP_PROXY, 0);
  args.SetMaxReceiveMessageSize(kMaxMessageBytes);
  args.SetMaxSendMessageSize(kMaxMessageBytes);
  // Reconnect quickly after a coordinator restart (gRPC's defaults back off up to 2 min).
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 250);
  args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 250);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 5000);
  // A subscriber can wait hours for the next version: notice a dead connection meanwhile.
  args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, kKeepaliveMs);
  args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, kKeepaliveTimeoutMs);
  std::shared_ptr<grpc::ChannelCredentials> creds;
  if (c.caFile.empty()) {
    creds = grpc::InsecureChannelCredentials();
  } else {
    std::ifstream in(c.caFile);
    if (!in) throw InputError("cannot read the CA file " + c.caFile);
    std::stringstream pem;
    pem << in.rdbuf();
    grpc::SslCredentialsOptions ssl;
    ssl.pem_root_certs = pem.str();
    creds = grpc::SslCredentials(ssl);
  }
  return grpc::CreateCustomChannel(c.address, creds, args);
}

void prepare(grpc::ClientContext& ctx, const Connection& c, double seconds) {
  if (!c.token.empty()) ctx.AddMetadata("authorization", "Bearer " + c.token);
  if (seconds > 0)
    ctx.set_deadline(std::chrono::system_clock::now() +
                     std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000)));
}

}  // namespace cpvs::net
