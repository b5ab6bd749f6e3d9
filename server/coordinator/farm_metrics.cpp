#include "coordinator/farm_metrics.h"

#include "cpvs/metrics/families.h"

namespace cpvs::server {

namespace {

using prometheus::Histogram;

// Sub-DAGs and artifacts: a kilobyte to tens of gigabytes.
const Histogram::BucketBoundaries kBytes = {1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10};

const char* const kJobStates[] = {"queued", "running", "merging", "done", "failed", "cancelled"};

}  // namespace

FarmMetrics::FarmMetrics()
    : registry_(std::make_shared<prometheus::Registry>()),
      leases_(prometheus::BuildCounter()
                  .Name("cpvs_leases_total")
                  .Help("Tile leases by what became of them: granted, completed, late (a result after another "
                        "was taken), failed_tile, failed_worker, failed_scene, interrupted, expired")
                  .Register(*registry_)),
      stageSeconds_(prometheus::BuildHistogram()
                        .Name("cpvs_tile_stage_seconds")
                        .Help("Seconds of each stage of a tile's bake, as its worker reported them")
                        .Register(*registry_)),
      resultBytes_(metrics::histogram(*registry_, "cpvs_tile_result_bytes",
                                      "Bytes of the encoded sub-DAGs workers returned", kBytes)),
      mergeSeconds_(metrics::histogram(*registry_, "cpvs_merge_tile_seconds",
                                       "Seconds the coordinator took to merge one tile into its job's DAG",
                                       metrics::kStageSecondsBuckets)),
      artifactSeconds_(metrics::histogram(*registry_, "cpvs_artifact_write_seconds",
                                          "Seconds to encode and write a finished job's artifact",
                                          metrics::kStageSecondsBuckets)),
      artifactBytesWritten_(
          metrics::counter(*registry_, "cpvs_artifact_written_bytes_total", "Bytes of artifacts written")),
      streams_(prometheus::BuildGauge()
                   .Name("cpvs_streams_open")
                   .Help("Long-lived streams open: watch (WatchJob), subscribe (sun-track subscribers)")
                   .Register(*registry_)),
      jobs_(prometheus::BuildGauge().Name("cpvs_jobs").Help("Jobs held, by state").Register(*registry_)),
      tiles_(prometheus::BuildGauge()
                 .Name("cpvs_tiles_outstanding")
                 .Help("Tiles of unfinished jobs not yet returned: queued (waiting for a worker) or leased "
                       "(being baked); their sum is what the workers' autoscaler follows")
                 .Register(*registry_)),
      mergeBacklog_(metrics::gauge(*registry_, "cpvs_merge_backlog",
                                   "Returned tiles and finished jobs waiting for the merge thread")),
      artifactBytes_(metrics::gauge(*registry_, "cpvs_artifacts_stored_bytes",
                                    "Bytes of the finished artifacts the coordinator holds")),
      storeBytes_(metrics::gauge(*registry_, "cpvs_store_bytes", "Bytes of the job database and its write-ahead log")),
      storeHealthy_(metrics::gauge(*registry_, "cpvs_store_healthy",
                                   "1 when the job database takes a write within half a second, else 0 (the health "
                                   "service then says NOT_SERVING)")),
      tracksActive_(metrics::gauge(*registry_, "cpvs_tracks_active", "Sun tracks publishing keyframes")),
      keyframeLag_(metrics::gauge(*registry_, "cpvs_track_keyframe_lag",
                                  "Keyframes a clock track's sun has reached that are not yet published (the largest "
                                  "over the tracks); above 0 its subscribers show an older sun")),
      process_(*registry_) {
  // Every series exists from the start, so that rates and alerts see zeros, not gaps.
  for (const char* e :
       {"granted", "completed", "late", "failed_tile", "failed_worker", "failed_scene", "interrupted", "expired"})
    leases_.Add({{"event", e}});
  for (const char* s : {"watch", "subscribe"}) streams_.Add({{"kind", s}});
  for (const char* s : {"queued", "leased"}) tiles_.Add({{"state", s}});
  for (const char* s : kJobStates) jobs_.Add({{"state", s}});
}

FarmMetrics::~FarmMetrics() = default;

void FarmMetrics::leaseGranted() { leases_.Add({{"event", "granted"}}).Increment(); }

void FarmMetrics::tileReturned(bool accepted, const std::map<std::string, double>& stages, uint64_t bytes) {
  leases_.Add({{"event", accepted ? "completed" : "late"}}).Increment();
  if (!accepted) return;
  for (const auto& [stage, seconds] : stages)
    stageSeconds_.Add({{"stage", stage}}, metrics::kStageSecondsBuckets).Observe(seconds);
  resultBytes_.Observe(double(bytes));
}

void FarmMetrics::tileFailed(const std::string& kind) {
  leases_.Add({{"event", kind == "interrupted" ? kind : "failed_" + kind}}).Increment();
}

void FarmMetrics::leasesExpired(uint64_t count) {
  if (count) leases_.Add({{"event", "expired"}}).Increment(double(count));
}

void FarmMetrics::tileMerged(double seconds) { mergeSeconds_.Observe(seconds); }

void FarmMetrics::artifactWritten(uint64_t bytes, double seconds) {
  artifactBytesWritten_.Increment(double(bytes));
  artifactSeconds_.Observe(seconds);
}

void FarmMetrics::streamsOpen(const std::string& kind, int delta) { streams_.Add({{"kind", kind}}).Increment(delta); }

void FarmMetrics::set(const FarmReadings& r) {
  for (const char* state : kJobStates) {
    const auto it = r.jobsByState.find(state);
    jobs_.Add({{"state", state}}).Set(it == r.jobsByState.end() ? 0 : double(it->second));
  }
  tiles_.Add({{"state", "queued"}}).Set(double(r.tilesQueued));
  tiles_.Add({{"state", "leased"}}).Set(double(r.tilesLeased));
  mergeBacklog_.Set(double(r.mergeBacklog));
  artifactBytes_.Set(double(r.artifactBytes));
  storeBytes_.Set(double(r.storeBytes));
  storeHealthy_.Set(r.storeHealthy ? 1 : 0);
  tracksActive_.Set(double(r.tracksActive));
  keyframeLag_.Set(double(r.keyframeLag));
  process_.refresh();
}

}  // namespace cpvs::server
