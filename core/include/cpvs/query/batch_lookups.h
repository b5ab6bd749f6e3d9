// The batched form of a lookup, shared by the CPVS and the shadow-map baseline so that
// both are timed and threaded the same way.
#pragma once

#include <tbb/parallel_for.h>

#include <string>
#include <vector>

#include "cpvs/base/error.h"
#include "cpvs/base/vec3.h"
#include "cpvs/query/normal_offset.h"

namespace cpvs {

/// out[i] = lookup.filtered(points[i], normals[i] or none, pcf), over all cores; the
/// width was validated once, when the PcfWidth was made.
template <class Lookup>
void batchLookups(const Lookup& lookup, const std::vector<Vec3>& points, const std::vector<Vec3>& normals, PcfWidth pcf,
                  std::vector<float>& out) {
  if (!normals.empty() && normals.size() != points.size())
    throw InputError("batch query: " + std::to_string(normals.size()) + " normals for " +
                     std::to_string(points.size()) + " points");
  out.resize(points.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, points.size(), 1024), [&](const auto& range) {
    for (size_t i = range.begin(); i != range.end(); ++i)
      out[i] = lookup.filtered(points[i], normals.empty() ? Vec3{} : normals[i], pcf);
  });
}

}  // namespace cpvs
