// What the coordinator tells Prometheus: events counted as they happen (leases granted,
// completed, failed, expired; tile stage seconds and result bytes as workers report them;
// merge seconds; streams open) and readings taken at each scrape (jobs and outstanding
// tiles by state, the merge backlog, stored artifact bytes, the store's size and health,
// the keyframe lag of clock tracks). The pending-tile gauge is what the workers'
// autoscaler follows.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>

#include <prometheus/counter.h>
#include <prometheus/family.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

#include "cpvs/metrics/process.h"

namespace cpvs::server {

/// What a scrape reads from the coordinator's state.
struct FarmReadings {
  std::map<std::string, uint64_t> jobsByState;  // queued, running, merging, done, failed, cancelled
  uint64_t tilesQueued = 0, tilesLeased = 0;
  uint64_t mergeBacklog = 0;                    // tiles and artifacts waiting for the merge thread
  uint64_t artifactBytes = 0;                   // finished artifacts held
  uint64_t storeBytes = 0;                      // the job database with its write-ahead log
  bool storeHealthy = true;
  uint64_t tracksActive = 0;
  uint64_t keyframeLag = 0;                     // the most keyframes a clock is ahead of its published ones
};

class FarmMetrics {
 public:
  FarmMetrics();
  ~FarmMetrics();
  std::shared_ptr<prometheus::Registry> registry() const { return registry_; }

  void leaseGranted();
  /// A worker's result taken (or refused as late: `accepted` false), with the seconds of
  /// each stage it reported and the encoded sub-DAG's bytes.
  void tileReturned(bool accepted, const std::map<std::string, double>& stages, uint64_t bytes);
  /// A tile given back: "tile", "worker", "scene" or "interrupted" (FailKind).
  void tileFailed(const std::string& kind);
  void leasesExpired(uint64_t count);
  void tileMerged(double seconds);
  void artifactWritten(uint64_t bytes, double seconds);
  /// Long-lived streams: "watch" (WatchJob) or "subscribe" (Subscribe); +1 or -1.
  void streamsOpen(const std::string& kind, int delta);

  /// The scrape's readings, with the process' own (memory, CPU, descriptors).
  void set(const FarmReadings& r);

 private:
  std::shared_ptr<prometheus::Registry> registry_;
  prometheus::Family<prometheus::Counter>& leases_;
  prometheus::Family<prometheus::Histogram>& stageSeconds_;
  prometheus::Histogram& resultBytes_;
  prometheus::Histogram& mergeSeconds_;
  prometheus::Histogram& artifactSeconds_;
  prometheus::Counter& artifactBytesWritten_;
  prometheus::Family<prometheus::Gauge>& streams_;
  prometheus::Family<prometheus::Gauge>& jobs_;
  prometheus::Family<prometheus::Gauge>& tiles_;
  prometheus::Gauge& mergeBacklog_;
  prometheus::Gauge& artifactBytes_;
  prometheus::Gauge& storeBytes_;
  prometheus::Gauge& storeHealthy_;
  prometheus::Gauge& tracksActive_;
  prometheus::Gauge& keyframeLag_;
  metrics::ProcessMetrics process_;
};

}  // namespace cpvs::server
