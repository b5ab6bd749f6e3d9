#include "partition_proxy.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <stdexcept>

namespace cpvs::testing {

struct PartitionProxy::Link {
  int client = -1, server = -1;
  std::atomic<bool> cut{false};
  std::thread pump;
  ~Link() {
    if (pump.joinable()) pump.join();
    ::close(client);
    ::close(server);
  }
};

namespace {

int connectTo(const std::string& target) {
  const size_t colon = target.rfind(':');
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(uint16_t(std::stoi(target.substr(colon + 1))));
  ::inet_pton(AF_INET, target.substr(0, colon).c_str(), &a.sin_addr);
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

}  // namespace

PartitionProxy::PartitionProxy(const std::string& target) : target_(target) {
  listener_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t size = sizeof a;
  if (::bind(listener_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(listener_, 64) != 0 ||
      ::getsockname(listener_, reinterpret_cast<sockaddr*>(&a), &size) != 0)
    throw std::runtime_error("the partition proxy cannot listen");
  port_ = ntohs(a.sin_port);
  acceptor_ = std::thread([this] { acceptLoop(); });
}

PartitionProxy::~PartitionProxy() {
  stopping_ = true;
  ::shutdown(listener_, SHUT_RDWR);
  acceptor_.join();
  ::close(listener_);
  std::lock_guard lock(mutex_);
  links_.clear();  // each pump sees stopping_ within its poll timeout
}

void PartitionProxy::cutOpenConnections() {
  std::lock_guard lock(mutex_);
  for (auto& link : links_) link->cut = true;
}

void PartitionProxy::acceptLoop() {
  while (!stopping_) {
    pollfd p{listener_, POLLIN, 0};
    if (::poll(&p, 1, 100) <= 0) continue;
    const int client = ::accept4(listener_, nullptr, nullptr, SOCK_CLOEXEC);
    if (client < 0) continue;
    const int server = connectTo(target_);
    if (server < 0) {
      ::close(client);
      continue;
    }
    ++accepted_;
    auto link = std::make_shared<Link>();
    link->client = client;
    link->server = server;
    Link* l = link.get();
    link->pump = std::thread([this, l] {
      char buf[65536];
      while (!stopping_ && !l->cut) {
        pollfd fds[2] = {{l->client, POLLIN, 0}, {l->server, POLLIN, 0}};
        if (::poll(fds, 2, 100) <= 0 || l->cut) continue;
        for (int i = 0; i < 2; ++i) {
          if (!(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
          const ssize_t n = ::read(fds[i].fd, buf, sizeof buf);
          if (n <= 0) {
            // A peer closed: close both, as a plain forwarder would.
            ::shutdown(l->client, SHUT_RDWR);
            ::shutdown(l->server, SHUT_RDWR);
            return;
          }
          for (ssize_t sent = 0; sent < n;) {
            const ssize_t w = ::write(fds[1 - i].fd, buf + sent, size_t(n - sent));
            if (w <= 0) return;
            sent += w;
          }
        }
      }
      // Cut: the sockets stay open and silent until the proxy goes.
      while (!stopping_) ::usleep(100000);
    });
    std::lock_guard lock(mutex_);
    links_.push_back(std::move(link));
  }
}

}  // namespace cpvs::testing
