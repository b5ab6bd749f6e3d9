// What a worker tells Prometheus: its tiles by outcome, the seconds of each stage of its
// bakes, its slots and how many are busy, whether it is draining, and the standard
// process families. A fleet's sum of busy slots against its slots is its utilisation.
#pragma once

#include <map>
#include <memory>
#include <string>

#include <prometheus/counter.h>
#include <prometheus/family.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

#include "cpvs/metrics/process.h"

namespace cpvs::worker {

class WorkerMetrics {
 public:
  explicit WorkerMetrics(int slots);
  ~WorkerMetrics();
  std::shared_ptr<prometheus::Registry> registry() const { return registry_; }

  /// A tile's end: "returned" (its result sent; `stages` its seconds), "failed" (given
  /// back as the tile's fault), "given_back" (the worker's own trouble or a stop), "lost"
  /// (the coordinator unreachable).
  void tileEnded(const std::string& outcome, const std::map<std::string, double>& stages = {});
  void slotBusy(int delta);
  void unreachable();
  void draining();
  /// Reads the process' own figures (call before a scrape).
  void refresh();

 private:
  std::shared_ptr<prometheus::Registry> registry_;
  prometheus::Family<prometheus::Counter>& tiles_;
  prometheus::Family<prometheus::Histogram>& stageSeconds_;
  prometheus::Gauge& busy_;
  prometheus::Gauge& draining_;
  prometheus::Counter& unreachable_;
  metrics::ProcessMetrics process_;
};

}  // namespace cpvs::worker
