#include "worker_metrics.h"

#include <prometheus/counter.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

namespace cpvs::worker {

namespace {

// The coordinator's tile-stage buckets: milliseconds to the hour a lease may be renewed for.
const prometheus::Histogram::BucketBoundaries kSeconds = {0.01, 0.03, 0.1, 0.3, 1, 3, 10, 30, 100, 300, 1000, 3600};

}  // namespace

WorkerMetrics::WorkerMetrics(int slots)
    : registry_(std::make_shared<prometheus::Registry>()),
      tiles_(prometheus::BuildCounter()
                 .Name("cpvs_worker_tiles_total")
                 .Help("Tiles this worker leased, by how they ended: returned, failed (the tile's fault), "
                       "given_back (the worker's own trouble, or a stop), lost (the coordinator unreachable: its lease expires)")
                 .Register(*registry_)),
      stageSeconds_(prometheus::BuildHistogram()
                        .Name("cpvs_worker_tile_stage_seconds")
                        .Help("Seconds of each stage of the tiles this worker returned")
                        .Register(*registry_)),
      busy_(prometheus::BuildGauge()
                .Name("cpvs_worker_slots_busy")
                .Help("Slots baking a tile now")
                .Register(*registry_)
                .Add({})),
      draining_(prometheus::BuildGauge()
                    .Name("cpvs_worker_draining")
                    .Help("1 once the worker was asked to stop: it takes no new tiles")
                    .Register(*registry_)
                    .Add({})),
      unreachable_(prometheus::BuildCounter()
                       .Name("cpvs_worker_coordinator_unreachable_total")
                       .Help("Calls to the coordinator that found it unreachable (each backed off and retried)")
                       .Register(*registry_)
                       .Add({})),
      process_(*registry_) {
  prometheus::BuildGauge()
      .Name("cpvs_worker_slots")
      .Help("Tiles this worker bakes at once (--slots)")
      .Register(*registry_)
      .Add({})
      .Set(slots);
  for (const char* o : {"returned", "failed", "given_back", "lost"}) tiles_.Add({{"outcome", o}});
}

WorkerMetrics::~WorkerMetrics() = default;

void WorkerMetrics::tileEnded(const std::string& outcome, const std::map<std::string, double>& stages) {
  tiles_.Add({{"outcome", outcome}}).Increment();
  for (const auto& [stage, seconds] : stages) stageSeconds_.Add({{"stage", stage}}, kSeconds).Observe(seconds);
}

void WorkerMetrics::slotBusy(int delta) { busy_.Increment(delta); }

void WorkerMetrics::unreachable() { unreachable_.Increment(); }

void WorkerMetrics::draining() { draining_.Set(1); }

void WorkerMetrics::refresh() { process_.refresh(); }

}  // namespace cpvs::worker
