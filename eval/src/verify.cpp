#include "cpvs/eval/verify.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include "cpvs/base/split_mix64.h"

namespace cpvs {

std::vector<SurfaceSample> sampleSurfaces(const Scene& scene, const RayScene& rays, ClosedMode closed,
                                          const Vec3& lightDir, uint64_t count, uint64_t seed) {
  size_t tris = scene.triangleCount();
  std::vector<double> cdf(tris + 1, 0.0);
  for (size_t t = 0; t < tris; ++t) {
    Vec3 a = scene.vertex(t, 0), b = scene.vertex(t, 1), c = scene.vertex(t, 2);
    cdf[t + 1] = cdf[t] + 0.5 * length(cross(b - a, c - a));
  }
  std::vector<SurfaceSample> out(count);
  if (tris == 0 || !(cdf[tris] > 0)) return {};
  tbb::parallel_for(uint64_t(0), count, [&](uint64_t i) {
    SplitMix64 rng = SplitMix64::forItem(seed, i);
    double pick = rng.uniform01() * cdf[tris];
    size_t t = size_t(std::upper_bound(cdf.begin(), cdf.end(), pick) - cdf.begin());
    t = std::clamp<size_t>(t, 1, tris) - 1;
    double r1 = rng.uniform01(), r2 = rng.uniform01();
    if (r1 + r2 > 1) {
      r1 = 1 - r1;
      r2 = 1 - r2;
    }
    Vec3 a = scene.vertex(t, 0), b = scene.vertex(t, 1), c = scene.vertex(t, 2);
    Vec3 n = normalize(cross(b - a, c - a));
    if (!rays.triangleClosed(uint32_t(t), closed) && dot(n, lightDir) > 0) n = -n;
    out[i] = SurfaceSample{a + (b - a) * r1 + (c - a) * r2, n};
  });
  return out;
}

double shadowRayLength(const OrthoGrid& g) { return 2.0 * (g.depthExtent + g.extent) + 1.0; }

bool exactlyLit(const RayScene& rays, const OrthoGrid& grid, const Vec3& point) {
  return !rays.occluded(point, -grid.frame.dir, 0.0, shadowRayLength(grid));
}

VerifyResult verifyArtifact(const ShadowQuery& query, ClosedMode closed, const Scene& scene, const RayScene& rays,
                            uint64_t count, uint64_t seed) {
  const OrthoGrid& g = query.grid();
  auto samples = sampleSurfaces(scene, rays, closed, g.frame.dir, count, seed);
  const double len = shadowRayLength(g);
  const Vec3 toLight = -g.frame.dir;
  // "Within one voxel" of a shadow boundary: the exact visibility is not the same at
  // every point of the 3x3x3 voxel block around the query point, sampled at its corners
  // and mid-points (offsets of -1, -1/2, 0, 1/2, 1 voxel along u, v and the light).
  std::vector<Vec3> neighbours;  // in voxels
  const double steps[] = {-1, -0.5, 0, 0.5, 1};
  for (double a : steps)
    for (double b : steps)
      for (double c : steps)
        if (a != 0 || b != 0 || c != 0) neighbours.push_back(Vec3{a, b, c});

  std::atomic<uint64_t> used{0}, inside{0}, near{0}, badNear{0}, badElse{0};
  std::mutex examplesMutex;
  VerifyResult result;
  tbb::parallel_for(size_t(0), samples.size(), [&](size_t i) {
    const SurfaceSample& s = samples[i];
    Vec3 q = query.offsetPoint(s.point, s.normal, 1);
    if (rays.closedNesting(q, toLight, len, closed) > 0) {  // no query can come from there
      ++inside;
      return;
    }
    ++used;
    bool exact = !rays.occluded(q, toLight, 0.0, len);
    bool cpvs = !query.voxelShadowed(query.voxelOf(s.point, s.normal, 1));
    const Vec3 qv = g.voxelFromWorld(q);
    bool isNear = false;
    for (const Vec3& o : neighbours)
      if (exactlyLit(rays, g, g.worldFromVoxel(qv + o)) != exact) {
        isNear = true;
        break;
      }
    // The bake samples each texel column through its centre: the centre of the query's
    // texel, at the query's depth and one slice either side, is within one voxel too.
    const Vec3 centre{std::floor(qv.x) + 0.5, std::floor(qv.y) + 0.5, qv.z};
    for (double dz = -1; dz <= 1 && !isNear; ++dz)
      isNear = exactlyLit(rays, g, g.worldFromVoxel(centre + Vec3{0, 0, dz})) != exact;
    // Closed interiors hold undefined voxels that the bake may resolve either way; a
    // query within one voxel of one (a receiver in a concave corner beside a closed
    // wall) is as near a boundary as one beside a shadow edge. Tested for mismatches only.
    if (!isNear && cpvs != exact)
      for (size_t k = 0; k < neighbours.size() && !isNear; ++k)
        isNear = rays.closedNesting(g.worldFromVoxel(qv + neighbours[k]), toLight, len, closed) > 0;
    near += isNear;
    if (cpvs == exact) return;
    if (isNear) {
      ++badNear;
    } else {
      ++badElse;
      std::lock_guard lock(examplesMutex);
      if (result.elsewhereExamples.size() < 16) result.elsewhereExamples.push_back(s);
    }
  });
  result.samples = used;
  result.insideClosed = inside;
  result.nearBoundary = near;
  result.mismatchNearBoundary = badNear;
  result.mismatchElsewhere = badElse;
  return result;
}

}  // namespace cpvs
