#include "cpvs/bake/texel_slices.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

#include "cpvs/base/error.h"

namespace cpvs {

namespace {

// Rays travel in packets of 8 covering 4 x 2 texels; blocks are aligned to global texel
// coordinates so a texel always shares its packet with the same neighbours.
constexpr int kPacketW = 4, kPacketH = 2;
static_assert(kPacketW * kPacketH == kPacketLanes);

}  // namespace

int orderCrossings(RayHit* hits, int count, double tieDistance) {
  // Rays cross a handful of surfaces: an insertion sort beats std::sort there, and the
  // in-place partition below, unlike std::stable_partition, never allocates (which it did
  // once per texel leaving a closed part).
  if (count > 32) {
    std::sort(hits, hits + count, closerCrossing);
  } else {
    for (int i = 1; i < count; ++i) {
      const RayHit h = hits[i];
      int j = i;
      for (; j > 0 && closerCrossing(h, hits[j - 1]); --j) hits[j] = hits[j - 1];
      hits[j] = h;
    }
  }
  // Surfaces that coincide (a box standing on another) are computed from different
  // triangles and land a few ulps apart in either order; within a run of crossings closer
  // than tieDistance, enters go first so that the count never touches zero between them.
  for (int i = 0; i < count;) {
    int j = i + 1;
    while (j < count && hits[j].t - hits[j - 1].t <= tieDistance) ++j;
    for (int k = i + 1, fronts = hits[i].front ? i + 1 : i; k < j; ++k) {
      if (!hits[k].front) continue;
      std::rotate(hits + fronts, hits + k, hits + k + 1);  // stable: the backs between move up
      ++fronts;
    }
    i = j;
  }
  // A ray through a shared edge or vertex reports each triangle around it: crossings of
  // the same kind within tieDistance are one crossing.
  int n = 0;
  for (int i = 0; i < count; ++i) {
    bool dup = false;
    for (int j = n - 1; j >= 0 && std::abs(hits[i].t - hits[j].t) <= tieDistance; --j)
      if (hits[j].front == hits[i].front && hits[j].closed == hits[i].closed) {
        dup = true;
        break;
      }
    if (!dup) hits[n++] = hits[i];
  }
  return n;
}

int exitCrossing(const RayHit* hits, int count, bool exact) {
  if (count == 0) return -1;
  // Only a closed surface entered from its front side opens an interior.
  if (!hits[0].closed || !hits[0].front) return -1;
  if (!exact) {
    for (int i = 1; i < count; ++i)
      if (hits[i].closed && !hits[i].front) return i;
    return -1;
  }
  int depth = 0;
  for (int i = 0; i < count; ++i) {
    if (!hits[i].closed) continue;
    depth += hits[i].front ? 1 : -1;
    if (depth < 0) return -1;  // inconsistent orientation: no interior is trusted
    if (depth == 0) return i;
  }
  return -1;  // never left the interior (open geometry forced closed): keep the column defined
}

namespace {

// The texels [x0, x0 + width) x [y0, y0 + height) through `texels` (rays and slices);
// crossings closer than dedupT are one crossing seen twice (Embree's robust mode reports
// a ray through a shared edge on both triangles); `skip(gx, gy)` texels cast no ray and
// are all undefined (a spot light's cone misses them).
template <class Texels, class Skip>
void renderTexels(const RayScene& rays, const Texels& texels, double dedupT, Skip skip, ClosedMode closed, ExitMode exit,
                  uint64_t x0, uint64_t y0, uint32_t width, uint32_t height, TexelSlices& out) {
  CPVS_CHECK(width % 8 == 0 && height % 8 == 0);
  const uint32_t R = texels.side();
  out.firstUndefined.assign(size_t(width) * height, R);
  out.firstShadowed.assign(size_t(width) * height, R);
  const bool exact = exit == ExitMode::Exact;
  // Without closed geometry only the first hit decides a texel: no need for all of them.
  const bool allHits = exact && rays.anyClosed(closed);

  const uint32_t rowsOfPackets = height / kPacketH;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, rowsOfPackets, 4), [&](const auto& range) {
    std::array<RayCrossings, kPacketLanes> lanes;
    std::array<RayHit, kMaxHitsPerRay> sorted;
    std::array<RayHit, kPacketLanes> first, back;
    std::array<bool, kPacketLanes> found, foundBack;
    RayPacket packet;
    for (uint32_t pr = range.begin(); pr != range.end(); ++pr) {
      for (uint32_t px = 0; px < width; px += kPacketW) {
        for (int l = 0; l < kPacketLanes; ++l) {
          const uint64_t gx = x0 + px + (l % kPacketW), gy = y0 + uint64_t(pr) * kPacketH + (l / kPacketW);
          const TexelRay ray = texels.ray(gx, gy);
          packet.origin[size_t(l)] = ray.origin;
          packet.dir[size_t(l)] = ray.dir;
          packet.tNear[size_t(l)] = 0.0f;
          packet.tFar[size_t(l)] = float(ray.tMax);
          packet.active[size_t(l)] = !skip(gx, gy);
        }
        if (allHits) {
          rays.allCrossings(packet, closed, lanes);
        } else {
          // Each lane's closest hit and, behind a closed front face, the first closed
          // back face, in one traversal.
          rays.firstHitsAndClosedBackFaces(packet, closed, first, found, back, foundBack);
          for (size_t l = 0; l < size_t(kPacketLanes); ++l) {
            lanes[l].count = found[l] ? (foundBack[l] ? 2 : 1) : 0;
            lanes[l].overflow = false;
            if (found[l]) lanes[l].hits[0] = first[l];
            if (foundBack[l]) lanes[l].hits[1] = back[l];
          }
        }

        for (int l = 0; l < kPacketLanes; ++l) {
          RayCrossings& lh = lanes[size_t(l)];
          int n = 0;
          if (!lh.overflow) {
            std::copy(lh.hits.begin(), lh.hits.begin() + lh.count, sorted.begin());
            n = orderCrossings(sorted.data(), lh.count, dedupT);
          } else {
            sorted[0] = lh.hits[0];  // too many crossings: keep the enter depth only
            for (int i = 1; i < lh.count; ++i)
              if (lh.hits[i].t < sorted[0].t) sorted[0] = lh.hits[i];
            sorted[0].closed = false;
            n = 1;
          }
          const uint32_t lx = px + (l % kPacketW), ly = pr * kPacketH + (l / kPacketW);
          const size_t at = size_t(ly) * width + lx;
          if (!packet.active[size_t(l)]) {
            out.firstUndefined[at] = 0;  // no light: every voxel is free
            out.firstShadowed[at] = R;
            continue;
          }
          classifyTexel(sorted.data(), n, exact, texels, out.firstUndefined[at], out.firstShadowed[at]);
        }
      }
    }
  });
}

}  // namespace

void renderTexelSlices(const RayScene& rays, const OrthoGrid& grid, ClosedMode closed, ExitMode exit,
                       uint64_t x0, uint64_t y0, uint32_t width, uint32_t height,
                       TexelSlices& out) {
  renderTexels(rays, grid.texelMapping(rays.origin()), grid.sceneDepthExtent() * 1e-6, [](uint64_t, uint64_t) { return false; },
               closed, exit, x0, y0, width, height, out);
}

void renderTexelSlices(const RayScene& rays, const PerspectiveGrid& grid, double tanCone, ClosedMode closed,
                       ExitMode exit, uint64_t x0, uint64_t y0, uint32_t width, uint32_t height, TexelSlices& out) {
  renderTexels(rays, grid.texelMapping(rays.origin()), grid.far() * 1e-6,
               [&](uint64_t gx, uint64_t gy) { return grid.coneMissesTexel(gx, gy, tanCone); }, closed, exit, x0, y0,
               width, height, out);
}

}  // namespace cpvs
