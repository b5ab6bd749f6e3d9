#include "cpvs/net/channel.h"

#include <chrono>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "cpvs/base/error.h"

namespace cpvs::net {

bool isLoopbackAddress(const std::string& hostPort) {
  if (hostPort.rfind("unix:", 0) == 0 || hostPort.rfind("unix-abstract:", 0) == 0) return true;
  std::string host = hostPort;
  if (!host.empty() && host[0] == '[') {
    host = host.substr(1, host.find(']') == std::string::npos ? std::string::npos : host.find(']') - 1);
  } else if (auto colon = host.rfind(':'); colon != std::string::npos && host.find(':') == colon) {
    host.resize(colon);
  }
  if (host.rfind("ipv4:", 0) == 0) host = host.substr(5);
  if (host == "localhost" || host == "::1") return true;
  // 127.0.0.0/8, written as four decimal numbers.
  unsigned a, b, c, d;
  char tail;
  return std::sscanf(host.c_str(), "%u.%u.%u.%u%c", &a, &b, &c, &d, &tail) == 4 && a == 127 && b < 256 && c < 256 &&
         d < 256;
}

std::shared_ptr<grpc::Channel> makeChannel(const Connection& c) {
  if (!c.token.empty() && c.caFile.empty() && !c.allowPlaintextToken && !isLoopbackAddress(c.address))
    throw InputError("refusing to send a token in plaintext to " + c.address +
                     ": give --ca (the farm's CA certificate) to use TLS, or --allow-plaintext-token on a private "
                     "network you trust");
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
  // A channel of its own connections: one made anew after a silent partition must not
  // pick up the old channel's dead connection from gRPC's process-wide pool.
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  if (!c.tlsName.empty()) args.SetSslTargetNameOverride(c.tlsName);
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
    for (const auto& [file, into] : {std::pair{&c.certFile, &ssl.pem_cert_chain}, {&c.keyFile, &ssl.pem_private_key}}) {
      if (file->empty()) continue;
      std::ifstream f(*file);
      if (!f) throw InputError("cannot read " + *file);
      std::stringstream text;
      text << f.rdbuf();
      *into = text.str();
    }
    creds = grpc::SslCredentials(ssl);
    // Over TLS the token travels as call credentials, which gRPC refuses to send on a
    // connection without privacy and integrity.
    if (!c.token.empty()) creds = grpc::CompositeChannelCredentials(creds, grpc::AccessTokenCredentials(c.token));
  }
  return grpc::CreateCustomChannel(c.address, creds, args);
}

void prepare(grpc::ClientContext& ctx, const Connection& c, double seconds) {
  // Plaintext (loopback, or allowed): the token as metadata; over TLS the channel's call
  // credentials carry it.
  if (!c.token.empty() && c.caFile.empty()) ctx.AddMetadata("authorization", "Bearer " + c.token);
  if (seconds > 0)
    ctx.set_deadline(std::chrono::system_clock::now() +
                     std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000)));
}

}  // namespace cpvs::net
