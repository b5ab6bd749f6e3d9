// Metric families of one series (no labels), built and registered in one call, and the
// buckets the farm's processes share: what the coordinator's, the workers' and the
// process figures are made of.
#pragma once

#include <prometheus/counter.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

namespace cpvs::metrics {

/// Seconds of a tile's stages and merges: milliseconds to the hour a lease may be renewed for.
inline const prometheus::Histogram::BucketBoundaries kStageSecondsBuckets = {0.01, 0.03, 0.1, 0.3, 1,    3,
                                                                             10,   30,   100, 300, 1000, 3600};

inline prometheus::Gauge& gauge(prometheus::Registry& r, const char* name, const char* help) {
  return prometheus::BuildGauge().Name(name).Help(help).Register(r).Add({});
}

inline prometheus::Counter& counter(prometheus::Registry& r, const char* name, const char* help) {
  return prometheus::BuildCounter().Name(name).Help(help).Register(r).Add({});
}

inline prometheus::Histogram& histogram(prometheus::Registry& r, const char* name, const char* help,
                                        const prometheus::Histogram::BucketBoundaries& buckets) {
  return prometheus::BuildHistogram().Name(name).Help(help).Register(r).Add({}, buckets);
}

}  // namespace cpvs::metrics
