#include "cpvs/metrics/endpoint.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <poll.h>
#include <prometheus/registry.h>
#include <prometheus/text_serializer.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <mutex>
#include <thread>

#include "cpvs/base/error.h"

// A small HTTP/1.1 server of its own, plaintext or TLS through OpenSSL: Debian 12's
// civetweb (what prometheus-cpp's exposer serves with) looks up OpenSSL 1.1 symbols
// that OpenSSL 3 no longer exports and crashes on its first TLS connection. One GET at
// a time is all a scrape needs; every connection is closed after its answer.
namespace cpvs::metrics {

namespace {

constexpr size_t kMaxRequestBytes = 16 * 1024;
constexpr int kIoTimeoutSeconds = 10;

/// HOST:PORT as an IPv4 or IPv6 socket address ("localhost": the loopback address).
sockaddr_storage parseAddress(const std::string& listen, socklen_t& length) {
  const size_t colon = listen.rfind(':');
  if (colon == std::string::npos || colon + 1 == listen.size())
    throw InputError("the metrics address " + listen + " is not HOST:PORT");
  std::string host = listen.substr(0, colon);
  const std::string port = listen.substr(colon + 1);
  if (port.find_first_not_of("0123456789") != std::string::npos || port.size() > 5 || std::stoi(port) > 65535)
    throw InputError("the metrics address " + listen + " has no port number 0-65535");
  if (host == "localhost") host = "127.0.0.1";
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  addrinfo hints{};
  hints.ai_flags = AI_NUMERICHOST | AI_NUMERICSERV | AI_PASSIVE;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  if (getaddrinfo(host.c_str(), port.c_str(), &hints, &found) != 0 || !found)
    throw InputError("the metrics address " + listen + " is not an IP address and port");
  sockaddr_storage out{};
  std::memcpy(&out, found->ai_addr, found->ai_addrlen);
  length = found->ai_addrlen;
  freeaddrinfo(found);
  return out;
}

std::string tlsError() {
  const unsigned long e = ERR_get_error();
  if (!e) return "unknown error";
  char text[256];
  ERR_error_string_n(e, text, sizeof text);
  return text;
}

/// The bearer token of a request's Authorization header; empty when there is none.
std::string bearerOf(const std::string& request) {
  static const std::string kHeader = "\r\nauthorization:";
  std::string lower = request;
  for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
  const size_t at = lower.find(kHeader);
  if (at == std::string::npos) return {};
  size_t start = at + kHeader.size();
  const size_t end = request.find("\r\n", start);
  std::string value = request.substr(start, end - start);
  value.erase(0, value.find_first_not_of(' '));
  static const std::string kScheme = "Bearer ";
  if (value.size() <= kScheme.size() || value.compare(0, kScheme.size(), kScheme) != 0) return {};
  value = value.substr(kScheme.size());
  value.erase(value.find_last_not_of(' ') + 1);
  return value;
}

/// A TLS context serving `cert` and `key`; InputError naming the file that is wrong.
SSL_CTX* tlsContext(const std::string& cert, const std::string& key) {
  SSL_CTX* ctx = SSL_CTX_new(TLS_server_method());
  if (!ctx) throw InputError("cannot set TLS up for the metrics endpoint: " + tlsError());
  SSL_CTX_set_min_proto_version(ctx, TLS1_2_VERSION);
  std::string wrong;
  if (SSL_CTX_use_certificate_chain_file(ctx, cert.c_str()) != 1) wrong = "metrics TLS certificate " + cert;
  else if (SSL_CTX_use_PrivateKey_file(ctx, key.c_str(), SSL_FILETYPE_PEM) != 1) wrong = "metrics TLS key " + key;
  else if (SSL_CTX_check_private_key(ctx) != 1) wrong = "metrics TLS key " + key + ", which does not match its certificate";
  if (!wrong.empty()) {
    SSL_CTX_free(ctx);
    throw InputError(wrong + ": " + tlsError());
  }
  return ctx;
}

/// When a file was last changed (0 when it cannot be read).
int64_t changedAt(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 ? int64_t(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec : 0;
}

}  // namespace

struct Endpoint::Server {
  EndpointOptions options;
  std::shared_ptr<prometheus::Registry> registry;
  std::function<void()> refresh;
  int listener = -1;
  SSL_CTX* tls = nullptr;
  int64_t tlsChangedAt = 0;  // the newer of the certificate's and the key's change times
  std::atomic<bool> stopping{false};
  std::thread thread;

  ~Server() {
    stopping = true;
    if (thread.joinable()) thread.join();
    if (listener >= 0) ::close(listener);
    if (tls) SSL_CTX_free(tls);
  }

  void loop() {
    while (!stopping) {
      pollfd p{listener, POLLIN, 0};
      if (::poll(&p, 1, 100) <= 0) continue;
      const int fd = ::accept(listener, nullptr, nullptr);
      if (fd < 0) continue;
      timeval timeout{kIoTimeoutSeconds, 0};
      setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
      setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof timeout);
      serve(fd);
      ::close(fd);
    }
  }

  // A renewed certificate (both files replaced) is served from the next connection on; a
  // pair that does not load yet (one file replaced so far) keeps the one served.
  void reloadTlsWhenChanged() {
    const int64_t changed = std::max(changedAt(options.tlsCert), changedAt(options.tlsKey));
    if (changed == tlsChangedAt) return;
    try {
      SSL_CTX* fresh = tlsContext(options.tlsCert, options.tlsKey);
      SSL_CTX_free(tls);
      tls = fresh;
      tlsChangedAt = changed;
    } catch (const InputError&) {
      ERR_clear_error();
    }
  }

  void serve(int fd) {
    SSL* ssl = nullptr;
    if (tls) {
      reloadTlsWhenChanged();
      ssl = SSL_new(tls);
      SSL_set_fd(ssl, fd);
      if (SSL_accept(ssl) != 1) {  // a plaintext request on the TLS port, an untrusting client
        SSL_free(ssl);
        ERR_clear_error();
        return;
      }
    }
    const auto receive = [&](char* buffer, int size) { return ssl ? SSL_read(ssl, buffer, size) : int(::recv(fd, buffer, size_t(size), 0)); };
    const auto send = [&](const std::string& bytes) {
      for (size_t sent = 0; sent < bytes.size();) {
        const int n = ssl ? SSL_write(ssl, bytes.data() + sent, int(bytes.size() - sent))
                          : int(::send(fd, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL));
        if (n <= 0) return;
        sent += size_t(n);
      }
    };
    std::string request;
    char buffer[4096];
    // A client that trickles its request does not hold the endpoint past the timeout.
    const auto giveUp = std::chrono::steady_clock::now() + std::chrono::seconds(kIoTimeoutSeconds);
    while (request.find("\r\n\r\n") == std::string::npos && request.size() < kMaxRequestBytes &&
           std::chrono::steady_clock::now() < giveUp) {
      const int n = receive(buffer, sizeof buffer);
      if (n <= 0) break;
      request.append(buffer, size_t(n));
    }
    send(answer(request));
    if (ssl) {
      SSL_shutdown(ssl);
      SSL_free(ssl);
    }
    ERR_clear_error();
  }

  static std::string response(const char* status, const std::string& extraHeaders, const std::string& body,
                              const char* type = "text/plain; charset=utf-8") {
    return std::string("HTTP/1.1 ") + status + "\r\nContent-Type: " + type + "\r\nContent-Length: " +
           std::to_string(body.size()) + "\r\nConnection: close\r\n" + extraHeaders + "\r\n" + body;
  }

  std::string answer(const std::string& request) {
    if (request.find("\r\n\r\n") == std::string::npos) return response("400 Bad Request", "", "incomplete request\n");
    const std::string line = request.substr(0, request.find("\r\n"));
    const size_t space = line.find(' '), second = line.find(' ', space + 1);
    if (space == std::string::npos || second == std::string::npos) return response("400 Bad Request", "", "bad request line\n");
    const std::string method = line.substr(0, space), target = line.substr(space + 1, second - space - 1);
    if (method != "GET" && method != "HEAD") return response("405 Method Not Allowed", "Allow: GET\r\n", "GET only\n");
    if (target != "/metrics" && target.rfind("/metrics?", 0) != 0) return response("404 Not Found", "", "see /metrics\n");
    if (options.authorize && !options.authorize(bearerOf(request)))
      return response("401 Unauthorized", "WWW-Authenticate: Bearer realm=\"cpvs metrics\"\r\n", "");
    std::string body;
    if (refresh) refresh();
    body = prometheus::TextSerializer().Serialize(registry->Collect());
    std::string r = response("200 OK", "", body, "text/plain; version=0.0.4; charset=utf-8");
    if (method == "HEAD") r.resize(r.size() - body.size());
    return r;
  }
};

Endpoint::Endpoint(EndpointOptions options, std::shared_ptr<prometheus::Registry> registry, std::function<void()> refresh)
    : server_(std::make_unique<Server>()) {
  const bool tls = !options.tlsCert.empty();
  if (tls == options.tlsKey.empty()) throw InputError("the metrics endpoint needs both a TLS certificate and key, or neither");
  Server& s = *server_;
  s.options = std::move(options);
  s.registry = std::move(registry);
  s.refresh = std::move(refresh);
  const std::string& listen = s.options.listen;
  if (tls) {
    s.tlsChangedAt = std::max(changedAt(s.options.tlsCert), changedAt(s.options.tlsKey));
    s.tls = tlsContext(s.options.tlsCert, s.options.tlsKey);
  }
  socklen_t length = 0;
  sockaddr_storage address = parseAddress(listen, length);
  s.listener = ::socket(address.ss_family, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (s.listener < 0) throw InputError("cannot serve metrics on " + listen + ": " + std::strerror(errno));
  const int yes = 1;
  setsockopt(s.listener, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  if (::bind(s.listener, reinterpret_cast<sockaddr*>(&address), length) != 0 || ::listen(s.listener, 16) != 0)
    throw InputError("cannot serve metrics on " + listen + ": " + std::strerror(errno));
  sockaddr_storage bound{};
  socklen_t boundLength = sizeof bound;
  getsockname(s.listener, reinterpret_cast<sockaddr*>(&bound), &boundLength);
  const uint16_t port = ntohs(bound.ss_family == AF_INET6 ? reinterpret_cast<sockaddr_in6*>(&bound)->sin6_port
                                                          : reinterpret_cast<sockaddr_in*>(&bound)->sin_port);
  address_ = listen.substr(0, listen.rfind(':')) + ":" + std::to_string(port);
  s.thread = std::thread([&s] { s.loop(); });
}

Endpoint::~Endpoint() = default;

}  // namespace cpvs::metrics
