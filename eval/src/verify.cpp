#include "cpvs/eval/verify.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include "cpvs/base/error.h"
#include "cpvs/eval/surface_sampling.h"
#include "cpvs/raytrace/visibility.h"

namespace cpvs {

TopTree verificationTree(const Scene& scene, const PsvLight& light) {
  TopTreeOptions options;
  options.frontFaceCulling = false;
  return TopTree::build(scene, light, options);
}

VerifyResult verifyArtifact(const ShadowQuery& query, ClosedMode closed, const Scene& scene, const RayScene& rays,
                            uint64_t count, uint64_t seed, const ExactOracles& oracles) {
  return verifySamples(query, closed, rays, sampleSurfaces(scene, rays, closed, query.grid().frame.dir, count, seed),
                       oracles);
}

VerifyResult verifySpotArtifact(const ShadowQuery& query, ClosedMode closed, const Scene& scene, const RayScene& rays,
                                uint64_t count, uint64_t seed, const std::vector<uint8_t>* sides,
                                const ExactOracles& oracles) {
  CPVS_CHECK(query.spot());
  return verifySamples(query, closed, rays,
                       sampleSpotSurfaces(scene, rays, closed, *query.spot(), query.tanCone(), count, seed, sides),
                       oracles);
}

// tan 43.5°: a cube face's inscribed cone, 1.5 degrees inside its square's edges.
constexpr double kFaceSampleTanCone = 0.9490;

VerifyResult verifyBundleGrid(const BundleQuery& query, size_t grid, ClosedMode closed, const Scene& scene,
                              const RayScene& rays, uint64_t count, uint64_t seed, const std::vector<uint8_t>* sides,
                              const ExactOracles& oracles) {
  const ShadowQuery& q = query.grid(grid);
  // A spot light's cone cuts its texels; a cube face's cone is wider than its square.
  if (query.light(query.lightOfGrid(grid)).light.kind == LightKind::Spot)
    return verifySpotArtifact(q, closed, scene, rays, count, seed, sides, oracles);
  return verifySamples(q, closed, rays,
                       sampleSpotSurfaces(scene, rays, closed, *q.spot(), kFaceSampleTanCone, count, seed, sides),
                       oracles);
}

namespace {

// The comparison of any binary lookup with the exact answer: `offsetPoint(s)` is the
// world point a lookup from sample s is made at, `lookupLit(s)` its answer. `sun` or
// `spot` (with its cone) is the light.
template <class OffsetPoint, class LookupLit>
VerifyResult verifyLookups(const LightGrid& g, const OrthoGrid* sun, const PerspectiveGrid* spot, double tanCone,
                           ClosedMode closed, const RayScene& rays, const std::vector<SurfaceSample>& samples,
                           const ExactOracles& oracles, OffsetPoint offsetPoint, LookupLit lookupLit) {
  CPVS_CHECK(oracles.psv || !oracles.psvOnly);
  auto toLight = [&](const Vec3& p) { return spot ? shadowRayTo(*spot, p) : shadowRayTo(*sun, p); };
  auto embreeLit = [&](const Vec3& p) {
    return spot ? exactlyLit(rays, *spot, tanCone, p) : exactlyLit(rays, *sun, p);
  };
  auto psvLit = [&](const Vec3& p) {
    if (spot && (!spot->insideCone(p, tanCone) || !(spot->depthOf(p) < spot->far()))) return false;
    return !oracles.psv->shadowed(p);
  };
  auto exactlyLitAt = [&](const Vec3& p) { return oracles.psvOnly ? psvLit(p) : embreeLit(p); };
  const bool second = oracles.psv && !oracles.psvOnly;
  // "Within one voxel" of a shadow boundary: the exact visibility is not the same at
  // every point of the 3x3x3 voxel block around the query point, sampled at its corners
  // and mid-points (offsets of -1, -1/2, 0, 1/2, 1 voxel along u, v and the light).
  std::vector<Vec3> neighbours;  // in voxels
  const double steps[] = {-1, -0.5, 0, 0.5, 1};
  for (double a : steps)
    for (double b : steps)
      for (double c : steps)
        if (a != 0 || b != 0 || c != 0) neighbours.push_back(Vec3{a, b, c});

  std::atomic<uint64_t> used{0}, inside{0}, lit{0}, near{0}, badNear{0}, badElse{0};
  std::atomic<uint64_t> compared{0}, disagreeNear{0}, disagreeElse{0};
  std::mutex examplesMutex;
  VerifyResult result;
  tbb::parallel_for(size_t(0), samples.size(), [&](size_t i) {
    const SurfaceSample& s = samples[i];
    const Vec3 q = offsetPoint(s);
    const ShadowRay ray = toLight(q);
    if (rays.closedNesting(q, ray.dir, ray.length, closed) > 0) {  // no query can come from there
      ++inside;
      return;
    }
    ++used;
    bool exact = exactlyLitAt(q);
    lit += exact;
    const bool cpvs = lookupLit(s);
    const Vec3 qv = g.voxelFromWorld(q);
    bool isNear = false;
    for (const Vec3& o : neighbours)
      if (exactlyLitAt(g.worldFromVoxel(qv + o)) != exact) {
        isNear = true;
        break;
      }
    // The bake samples each texel column through its centre: the centre of the query's
    // texel, at the query's depth and one slice either side, is within one voxel too.
    const Vec3 centre{std::floor(qv.x) + 0.5, std::floor(qv.y) + 0.5, qv.z};
    for (double dz = -1; dz <= 1 && !isNear; ++dz)
      isNear = exactlyLitAt(g.worldFromVoxel(centre + Vec3{0, 0, dz})) != exact;
    // Closed interiors hold undefined voxels that the bake may resolve either way; a
    // query within one voxel of one (a receiver in a concave corner beside a closed
    // wall) is as near a boundary as one beside a shadow edge. Tested for mismatches only.
    if (!isNear && cpvs != exact)
      for (size_t k = 0; k < neighbours.size() && !isNear; ++k)
      {
        const Vec3 p = g.worldFromVoxel(qv + neighbours[k]);
        const ShadowRay r = toLight(p);
        isNear = rays.closedNesting(p, r.dir, r.length, closed) > 0;
      }
    near += isNear;
    // An answer that differs from the exact one: near a boundary, or elsewhere (kept as an example).
    auto differs = [&](std::atomic<uint64_t>& atBoundary, std::atomic<uint64_t>& elsewhere,
                       std::vector<SurfaceSample>& examples) {
      if (isNear) {
        ++atBoundary;
        return;
      }
      ++elsewhere;
      std::lock_guard lock(examplesMutex);
      if (examples.size() < 16) examples.push_back(s);
    };
    if (second) {
      ++compared;
      if (psvLit(q) != exact) differs(disagreeNear, disagreeElse, result.disagreementExamples);
    }
    if (cpvs != exact) differs(badNear, badElse, result.elsewhereExamples);
  });
  result.samples = used;
  result.insideClosed = inside;
  result.exactlyLit = lit;
  result.nearBoundary = near;
  result.mismatchNearBoundary = badNear;
  result.mismatchElsewhere = badElse;
  result.oraclesCompared = compared;
  result.oraclesDisagreeNearBoundary = disagreeNear;
  result.oraclesDisagreeElsewhere = disagreeElse;
  return result;
}

}  // namespace

VerifyResult verifySamples(const ShadowQuery& query, ClosedMode closed, const RayScene& rays,
                           const std::vector<SurfaceSample>& samples, const ExactOracles& oracles) {
  return verifyLookups(
      query.lightGrid(), query.spot() ? nullptr : &query.grid(), query.spot(), query.tanCone(), closed, rays, samples,
      oracles, [&](const SurfaceSample& s) { return query.offsetPoint(s.point, s.normal, 1); },
      [&](const SurfaceSample& s) { return !query.voxelShadowed(query.voxelOf(s.point, s.normal, 1)); });
}

VerifyResult verifyDagMhSamples(const DagMhQuery& query, ClosedMode closed, const RayScene& rays,
                                const std::vector<SurfaceSample>& samples, const ExactOracles& oracles) {
  return verifyLookups(
      query.grid(), &query.grid(), nullptr, 0, closed, rays, samples, oracles,
      [&](const SurfaceSample& s) { return query.grid().worldFromVoxel(query.lookupVoxel(s.point, s.normal, 1)); },
      [&](const SurfaceSample& s) { return query.litTexels(s.point, s.normal, 1) == 1; });
}

}  // namespace cpvs
