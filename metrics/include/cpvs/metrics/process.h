// The standard process_* families every Prometheus client exports (resident and virtual
// memory, CPU seconds, open and allowed file descriptors, threads, start time), read from
// /proc at each scrape.
#pragma once

#include <memory>

namespace prometheus {
class Registry;
class Gauge;
class Counter;
}

namespace cpvs::metrics {

class ProcessMetrics {
 public:
  explicit ProcessMetrics(prometheus::Registry& registry);
  /// Reads /proc/self now (call before a scrape).
  void refresh();

 private:
  prometheus::Gauge& resident_;
  prometheus::Gauge& virtual_;
  prometheus::Gauge& openFds_;
  prometheus::Gauge& maxFds_;
  prometheus::Gauge& threads_;
  prometheus::Gauge& startTime_;
  prometheus::Counter& cpuSeconds_;
  double cpuSecondsSeen_ = 0;
};

}  // namespace cpvs::metrics
