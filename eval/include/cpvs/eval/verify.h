// Verification of a bake against exact ray-traced visibility at points on the scene.
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/psv/top_tree.h"
#include "cpvs/query/bundle_query.h"
#include "cpvs/query/dag_mh_query.h"
#include "cpvs/query/shadow_query.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/eval/surface_sampling.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

struct VerifyResult {
  uint64_t samples = 0;              // points compared
  uint64_t insideClosed = 0;         // offset points inside closed geometry: never queried, skipped
  uint64_t exactlyLit = 0;           // points the exact shadow ray finds lit
  uint64_t nearBoundary = 0;         // points whose exact visibility changes within one voxel
  uint64_t mismatchNearBoundary = 0;
  uint64_t mismatchElsewhere = 0;
  std::vector<SurfaceSample> elsewhereExamples;  // up to 16, for diagnosis
  // The second oracle (ExactOracles::psv beside Embree): points it answered, and where
  // the two exact answers differ, near a boundary or elsewhere (a bug in one of them).
  uint64_t oraclesCompared = 0;
  uint64_t oraclesDisagreeNearBoundary = 0;
  uint64_t oraclesDisagreeElsewhere = 0;
  std::vector<SurfaceSample> disagreementExamples;  // up to 16

  /// Adds another comparison's counts (and examples, up to 16).
  VerifyResult& operator+=(const VerifyResult& o) {
    samples += o.samples;
    insideClosed += o.insideClosed;
    exactlyLit += o.exactlyLit;
    nearBoundary += o.nearBoundary;
    mismatchNearBoundary += o.mismatchNearBoundary;
    mismatchElsewhere += o.mismatchElsewhere;
    oraclesCompared += o.oraclesCompared;
    oraclesDisagreeNearBoundary += o.oraclesDisagreeNearBoundary;
    oraclesDisagreeElsewhere += o.oraclesDisagreeElsewhere;
    for (const SurfaceSample& e : o.elsewhereExamples)
      if (elsewhereExamples.size() < 16) elsewhereExamples.push_back(e);
    for (const SurfaceSample& e : o.disagreementExamples)
      if (disagreementExamples.size() < 16) disagreementExamples.push_back(e);
    return *this;
  }

  double fractionNearBoundary() const { return samples ? double(mismatchNearBoundary) / double(samples) : 0; }
  double fractionElsewhere() const { return samples ? double(mismatchElsewhere) / double(samples) : 0; }
};

/// The exact visibility a verification compares with: Embree's shadow rays; with `psv`
/// (a TOP tree of the same light and scene) also the partitioned shadow volumes, a second
/// oracle that shares no code with the first, or (psvOnly) those alone.
struct ExactOracles {
  const TopTree* psv = nullptr;
  bool psvOnly = false;
};

/// A TOP tree of the scene for a light, as a verification's oracle: every triangle casts
/// (no front-face culling), so that it answers as a shadow ray does at every point, the
/// probes inside closed parts included.
TopTree verificationTree(const Scene& scene, const PsvLight& light);

/// Compares binary CPVS lookups with exact Embree shadow rays from the same offset points
/// (the lookup's own normal offset). A point counts as near a shadow boundary when the
/// exact visibility is not constant within one voxel of it: it differs at one of the 124
/// points offset by -1, -1/2, 0, 1/2 or 1 voxel along u, v and the light direction.
/// A mismatching point also counts as near when one of those points lies inside closed
/// geometry: the undefined voxels there may be resolved either way. Offset points inside
/// closed geometry (where no lookup can come from) are skipped.
VerifyResult verifyArtifact(const ShadowQuery& query, ClosedMode closed, const Scene& scene, const RayScene& rays,
                            uint64_t count, uint64_t seed, const ExactOracles& oracles = {});

/// The same for a spot light's query, at surface points inside its cone
/// (sampleSpotSurfaces): exact visibility is inside the cone and nothing on the segment to
/// the light, "within one voxel" is in the spot grid's voxels.
VerifyResult verifySpotArtifact(const ShadowQuery& query, ClosedMode closed, const Scene& scene, const RayScene& rays,
                                uint64_t count, uint64_t seed, const std::vector<uint8_t>* sides = nullptr,
                                const ExactOracles& oracles = {});

/// The same for grid k of a light bundle: a spot light's as verifySpotArtifact; a point
/// light's cube face at surface points inside the cone its square holds (less a margin of
/// a few degrees, so that every offset point stays in the face). With `sides`
/// (receivingSides of the declaration it was baked for), at receiving sides only
/// (sampleSpotSurfaces).
VerifyResult verifyBundleGrid(const BundleQuery& query, size_t grid, ClosedMode closed, const Scene& scene,
                              const RayScene& rays, uint64_t count, uint64_t seed,
                              const std::vector<uint8_t>* sides = nullptr, const ExactOracles& oracles = {});

/// The same comparison at given points (sampleReceivers: where a bake's declared
/// receivers are, the only points a bake for them answers exactly).
VerifyResult verifySamples(const ShadowQuery& query, ClosedMode closed, const RayScene& rays,
                           const std::vector<SurfaceSample>& samples, const ExactOracles& oracles = {});

/// The same comparison for binary DAG-MH lookups (the same normal offset; a point is
/// shadowed when its depth reaches the texel's stored one). Sample the receivers the file
/// serves: a `surfaces` DAG-MH answers points on surfaces only.
VerifyResult verifyDagMhSamples(const DagMhQuery& query, ClosedMode closed, const RayScene& rays,
                                const std::vector<SurfaceSample>& samples, const ExactOracles& oracles = {});

}  // namespace cpvs
