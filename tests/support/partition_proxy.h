// A TCP forwarder on 127.0.0.1 that can cut the connections through it silently, as a
// network partition does (no RST, no FIN: the peers' sockets stay open and nothing more
// arrives), while connections made afterwards go through again: a router that lost
// every flow it was carrying.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace cpvs::testing {

class PartitionProxy {
 public:
  /// Forwards a port of its own to `target` (HOST:PORT).
  explicit PartitionProxy(const std::string& target);
  ~PartitionProxy();
  PartitionProxy(const PartitionProxy&) = delete;
  PartitionProxy& operator=(const PartitionProxy&) = delete;

  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  /// Every connection open now stops carrying bytes, for good; later ones carry them.
  void cutOpenConnections();
  /// Connections accepted so far.
  int connections() const { return accepted_; }

 private:
  struct Link;
  void acceptLoop();

  std::string target_;
  int listener_ = -1, port_ = 0;
  std::atomic<bool> stopping_{false};
  std::atomic<int> accepted_{0};
  std::mutex mutex_;
  std::vector<std::shared_ptr<Link>> links_;
  std::thread acceptor_;
};

}  // namespace cpvs::testing
