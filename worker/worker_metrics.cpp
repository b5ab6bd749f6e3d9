#include "worker_metrics.h"

#include "cpvs/metrics/families.h"

namespace cpvs::worker {

WorkerMetrics::WorkerMetrics(int slots)
    : registry_(std::make_shared<prometheus::Registry>()),
      tiles_(prometheus::BuildCounter()
                 .Name("cpvs_worker_tiles_total")
                 .Help("Tiles this worker leased, by how they ended: returned, failed (the tile's fault), "
                       "given_back (the worker's own trouble, or a stop), lost (the coordinator unreachable: its lease "
                       "expires)")
                 .Register(*registry_)),
      stageSeconds_(prometheus::BuildHistogram()
                        .Name("cpvs_worker_tile_stage_seconds")
                        .Help("Seconds of each stage of the tiles this worker returned")
                        .Register(*registry_)),
      busy_(metrics::gauge(*registry_, "cpvs_worker_slots_busy", "Slots baking a tile now")),
      draining_(metrics::gauge(*registry_, "cpvs_worker_draining",
                               "1 once the worker was asked to stop: it takes no new tiles")),
      unreachable_(
          metrics::counter(*registry_, "cpvs_worker_coordinator_unreachable_total",
                           "Calls to the coordinator that found it unreachable (each backed off and retried)")),
      process_(*registry_) {
  metrics::gauge(*registry_, "cpvs_worker_slots", "Tiles this worker bakes at once (--slots)").Set(slots);
  for (const char* o : {"returned", "failed", "given_back", "lost"}) tiles_.Add({{"outcome", o}});
}

WorkerMetrics::~WorkerMetrics() = default;

void WorkerMetrics::tileEnded(const std::string& outcome, const std::map<std::string, double>& stages) {
  tiles_.Add({{"outcome", outcome}}).Increment();
  for (const auto& [stage, seconds] : stages)
    stageSeconds_.Add({{"stage", stage}}, metrics::kStageSecondsBuckets).Observe(seconds);
}

void WorkerMetrics::slotBusy(int delta) { busy_.Increment(delta); }

void WorkerMetrics::unreachable() { unreachable_.Increment(); }

void WorkerMetrics::draining() { draining_.Set(1); }

void WorkerMetrics::refresh() { process_.refresh(); }

}  // namespace cpvs::worker
