// Pictures of a scene lit by the sun, with CPVS shadows or exact ray-traced ones, and the
// difference between the two: how a person checks a bake by eye. Cameras: camera.h.
#pragma once

#include <tbb/parallel_for.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "cpvs/eval/image.h"
#include "cpvs/query/shadow_query.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/eval/camera.h"
#include "cpvs/light/ortho_grid.h"

namespace cpvs {

/// Visibility of the sun per pixel (1 lit, 0 shadowed, fractions with PCF) from any lookup
/// with `filtered(p, n, pcf)` (a CPVS's, a DAG-MH's), with its normal offset; pixels
/// without a hit get 1. Multithreaded.
template <class Lookup>
std::vector<float> lookupVisibility(const CameraHits& hits, const Lookup& lookup, int pcf) {
  const PcfWidth width(pcf);
  std::vector<float> vis(hits.pixels.size(), 1.0f);
  tbb::parallel_for(size_t(0), hits.pixels.size(), [&](size_t i) {
    const SurfaceHit& s = hits.pixels[i];
    if (s.hit) vis[i] = lookup.filtered(s.point, s.normal, width);
  });
  return vis;
}
/// The CPVS's.
std::vector<float> cpvsVisibility(const CameraHits& hits, const ShadowQuery& query, int pcf);
/// The same from exact Embree shadow rays leaving the surface itself (a tiny offset
/// against self-intersection, no voxel bias): the ground truth a viewer compares with.
std::vector<float> exactVisibility(const CameraHits& hits, const RayScene& rays, const OrthoGrid& grid);

/// Shades the hits: grey surfaces under sky light plus the sun times visibility; a sky
/// gradient where nothing was hit. Linear values.
/// `transmittance` (one per pixel, or null): the sun light let through translucent
/// casters, multiplying the sun's term channel by channel.
Image shadeHits(const CameraHits& hits, const std::vector<float>& visibility, const Vec3& lightDir,
                const std::vector<std::array<float, 3>>* transmittance = nullptr);

/// The picture seen through a homogeneous medium in the sun (sun shafts): each pixel's
/// colour attenuated along its view ray, plus the sun light the medium scatters towards
/// the eye on the ray's lit stretches (ShadowQuery::inScattering: exact for the voxels),
/// plus a dim sky light scattered all along it. The medium is a layer of fog between the
/// heights (Y) of the scene's box [lo, hi], without end across: past the box the sun
/// reaches it everywhere (in closed form), and a ray that leaves the layer sees the sky.
/// The sun's strength is shadeHits's. `boxInScattering`: each pixel's in-scattering on
/// its fogSegments segment as a device answered it (ShadowLookups::segments); null:
/// ShadowQuery::inScattering here.
Image foggedImage(const Image& clear, const CameraHits& hits, const Camera& camera, const ShadowQuery& query,
                  const Medium& medium, const Vec3& lo, const Vec3& hi,
                  const std::vector<float>* boxInScattering = nullptr);
/// The segments foggedImage walks through the sun's grid: each pixel's view ray in the
/// fog layer and the scene's box, from[i] to to[i] (from == to where it has none); what
/// a device answers for the same frame (GpuShadows::segments, bench_shafts).
void fogSegments(const CameraHits& hits, const Camera& camera, const Vec3& lo, const Vec3& hi, std::vector<Vec3>& from,
                 std::vector<Vec3>& to);

/// Where two visibilities disagree on a surface facing the sun: red where `a` is darker,
/// blue where it is brighter, the scene in dim grey elsewhere. Counts the sunlit-facing
/// pixels compared and those that differ by more than half.
Image differenceImage(const CameraHits& hits, const std::vector<float>& a, const std::vector<float>& b,
                      const Vec3& lightDir, uint64_t* compared, uint64_t* differing);

}  // namespace cpvs
