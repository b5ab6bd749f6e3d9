#include "rpc/gatekeeper.h"

#include <spdlog/spdlog.h>

#include <cmath>

#include "cpvs/base/text.h"

namespace cpvs::server {

namespace {

constexpr size_t kMaxPeers = 10000;

std::chrono::steady_clock::duration seconds(double s) {
  return std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(s));
}

}  // namespace

std::string peerHost(const std::string& peer) {
  std::string rest;
  if (peer.rfind("ipv4:", 0) == 0) rest = peer.substr(5);
  else if (peer.rfind("ipv6:", 0) == 0) rest = peer.substr(5);
  else return peer;
  if (!rest.empty() && rest.front() == '[') {
    const size_t close = rest.find(']');
    return close == std::string::npos ? rest : rest.substr(1, close - 1);
  }
  return rest.substr(0, rest.rfind(':'));
}

double Gatekeeper::lockedFor(const std::string& host) {
  std::lock_guard lock(mutex_);
  const auto it = peers_.find(host);
  if (it == peers_.end()) return 0;
  const auto left = it->second.lockedUntil - std::chrono::steady_clock::now();
  return left.count() > 0 ? std::chrono::duration<double>(left).count() : 0;
}

bool Gatekeeper::failed(const std::string& host) {
  if (limits_.limit <= 0) return false;
  std::lock_guard lock(mutex_);
  if (peers_.size() >= kMaxPeers && !peers_.count(host)) peers_.clear();
  Peer& p = peers_[host];
  const auto now = std::chrono::steady_clock::now();
  if (p.failures == 0 || now - p.windowStart > seconds(limits_.windowSeconds)) {
    p.failures = 0;
    p.windowStart = now;
  }
  if (++p.failures < limits_.limit) return false;
  p.failures = 0;
  p.lockedUntil = now + seconds(limits_.lockoutSeconds);
  return true;
}

grpc::Status Gatekeeper::admit(const grpc::ServerContext* ctx, Role needed, Access* access) {
  *access = Access::all();
  if (!tokens_.enabled()) return grpc::Status::OK;
  const std::string host = peerHost(ctx->peer());
  if (const double wait = lockedFor(host); wait > 0)
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                        "too many failed authentications from this address: try again in " +
                            std::to_string(int(std::ceil(wait))) + " s");
  const auto refuse = [&](const char* why) {
    if (failed(host))
      spdlog::warn("{} failed to authenticate {} times within {} s: refused for {} s", loggable(host), limits_.limit,
                   limits_.windowSeconds, limits_.lockoutSeconds);
    return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, why);
  };
  const auto& md = ctx->client_metadata();
  auto it = md.find("authorization");
  if (it == md.end()) {
    // A worker's own certificate instead of the shared worker token (mTLS): the handshake
    // verified it against --worker-ca, or the connection would not exist.
    const auto auth = ctx->auth_context();
    if (workerCertificates_ && auth && auth->IsPeerAuthenticated()) {
      const auto names = auth->FindPropertyValues("x509_common_name");
      const std::string name = names.empty() ? std::string("unnamed") : std::string(names.front().data(), names.front().size());
      *access = Access{"worker-certificate-" + name, false};
      if (!TokenTable::allows(Role::Worker, needed))
        return grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                            std::string("a worker's certificate cannot call this (needs ") + roleName(needed) + ")");
      return grpc::Status::OK;
    }
    return refuse("no bearer token");
  }
  std::string value(it->second.data(), it->second.size());
  const std::string prefix = "Bearer ";
  if (value.rfind(prefix, 0) != 0) return refuse("authorization is not a bearer token");
  const auto holder = tokens_.holderOf(value.substr(prefix.size()));  // one digest and one lookup per call
  if (!holder) return refuse("unknown token");
  const Role role = holder->role;
  *access = Access{holder->owner, role == Role::Admin};
  if (!TokenTable::allows(role, needed))
    return grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                        std::string("a ") + roleName(role) + " token cannot call this (needs " + roleName(needed) + ")");
  return grpc::Status::OK;
}

}  // namespace cpvs::server
