// The Prometheus endpoint of a farm process (coordinator or worker): GET /metrics on a
// port of its own, in Prometheus' text format, behind the same choice the process made
// for its RPCs: bearer tokens or none, TLS or plaintext (the certificate read again when
// its files change).
#pragma once

#include <functional>
#include <memory>
#include <string>

namespace prometheus {
class Registry;
}

namespace cpvs::metrics {

struct EndpointOptions {
  std::string listen;   // HOST:PORT (an IPv4 address or localhost); port 0 picks a free one
  std::string tlsCert;  // PEM chain and key: serve HTTPS (both or neither)
  std::string tlsKey;
  /// Whether a request's bearer token may read the metrics; empty: anyone who reaches
  /// the port may (a process whose RPCs take no tokens either).
  std::function<bool(const std::string& token)> authorize;
};

class Endpoint {
 public:
  /// Serves `registry`; `refresh` runs before each scrape (gauges read when asked, such
  /// as queue depths). InputError when the address cannot be served or TLS not set up.
  Endpoint(EndpointOptions options, std::shared_ptr<prometheus::Registry> registry, std::function<void()> refresh = {});
  ~Endpoint();
  Endpoint(const Endpoint&) = delete;
  Endpoint& operator=(const Endpoint&) = delete;

  /// HOST:PORT served, with the port bound.
  const std::string& address() const { return address_; }

 private:
  struct Server;
  std::unique_ptr<Server> server_;
  std::string address_;
};

}  // namespace cpvs::metrics
