// How accurate a bake is at each resolution, against exact ray-traced visibility and
// against plain shadow maps: the measurements behind choosing a resolution.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "cpvs/bake/bake.h"
#include "cpvs/light/frame.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/eval/render.h"
#include "cpvs/scene/source.h"

namespace cpvs {

/// "1K", "16K" for multiples of 1024, the number otherwise.
std::string resolutionLabel(uint64_t resolution);

/// Bins of a query point's distance to the exact shadow boundary, in texels of the row's
/// resolution R (extent / R): (0, 1], (1, 2], (2, 4], (4, 8], more than 8 (or none found).
constexpr int kDistanceBins = 5;
/// The bins' names in the report's tables and in its CSV columns.
struct DistanceBinName {
  const char* table;
  const char* csv;
};
constexpr std::array<DistanceBinName, kDistanceBins> kDistanceBinNames{
    {{"≤1 texel", "le1"}, {"1–2", "1_2"}, {"2–4", "2_4"}, {"4–8", "4_8"}, {">8", "gt8"}}};
/// The bin of a distance (world units) measured in texels of size `texel`.
int distanceBin(double distance, double texel);

/// Number of probe directions of boundaryDistance: 12 across the light (30 degrees apart
/// in u, v) and one towards the light.
constexpr int kBoundaryProbeDirections = 13;

/// Smallest |cos| between a receiver's normal and the light for which boundaryDistance's
/// probes follow the receiver's plane: below it the receiver lies within about 11.5 degrees
/// of parallel to the light.
constexpr double kFollowReceiverMinCos = 0.2;

/// Estimates the distance, across the light (in the u, v plane), from the query point q to
/// the nearest point whose exact visibility (exactlyLit) differs from q's: the distance to
/// the shadow boundary that texels quantize. Probes at radii r0, 2 r0, 4 r0, ... up to
/// rMax, at each radius in kBoundaryProbeDirections directions, and returns the first
/// radius at which a probe differs (the boundary then lies within it and, up to the
/// 15-degree gap between directions, beyond half of it), or +infinity when none does.
///  - Across the light, a probe moves r along a direction of the u, v plane and slides
///    along the light so that it stays on the plane through q parallel to the receiver
///    (normal n): at the same height over the receiver, as the query points of the
///    receiver's neighbours are. Without the slide, a probe on a sloped receiver would meet
///    the receiver itself within a few texels, which is no shadow edge. With n zero, or a
///    receiver almost parallel to the light (|cos| < kFollowReceiverMinCos: then it is a
///    boundary itself), probes stay at q's depth.
///  - Towards the light, a probe moves r along -dir: a shadowed point becomes lit past its
///    occluder (an occluder close in depth). Away from the light is not probed: a lit point
///    meets its own receiver there at the normal offset, and a shadowed one stays shadowed.
/// `lit` is q's own exact visibility.
double boundaryDistance(const RayScene& rays, const OrthoGrid& grid, const Vec3& q, const Vec3& n, bool lit, double r0,
                        double rMax);

/// The exact fraction of the light seen over a pcf x pcf filter footprint of texels of
/// size grid.extent / side (side = R gives the grid's own texels): the texels around the
/// one holding q in u, v, each sampled by perTexel x perTexel shadow rays (exactlyLit) from
/// stratified points at q's depth along the light, (a + 1/2) / perTexel across the texel.
/// perTexel = 1 samples each texel's centre, as a PCF lookup does (what it would answer
/// with exact depths); larger values estimate the area average that PCF approximates.
double exactFootprintLit(const RayScene& rays, const OrthoGrid& grid, uint32_t side, const Vec3& q, int pcf,
                         int perTexel = 1);

/// Rays per texel side of the area-average PCF reference (4 x 4 = 16 per texel).
constexpr int kAreaRaysPerTexelSide = 4;

/// The structures compared, per resolution R.
enum class AccuracyMethod : uint8_t {
  Cpvs = 0,                  // the CPVS baked at R
  ShadowMapEqualBytes = 1,   // 16-bit shadow map of side floor(sqrt(DAG bytes / 2)), its own normal offset
  ShadowMapEqualBytesCpvsOffset = 2,  // the same map, looked up at the CPVS's offset point
  ShadowMapFull = 3,         // 16-bit shadow map of side R (the CPVS's own texels)
  DagMh = 4,                 // the DAG-MH baked at R for the same receivers (bake_dag_mh.h), the CPVS's offset
  FloatMapFull = 5,          // float shadow map of side R (the CPVS's texels and offset points)
  CpvsEverywhere = 6,        // the CPVS baked at R for receivers everywhere (when others are declared)
};
constexpr int kAccuracyMethods = 7;
/// Human name ("CPVS", "shadow map, equal bytes", ...) and CSV key ("cpvs", "sm_equal_bytes", ...).
const char* accuracyMethodName(AccuracyMethod m);
const char* accuracyMethodKey(AccuracyMethod m);

/// PCF widths measured, besides binary lookups.
constexpr std::array<int, 3> kAccuracyPcfWidths{3, 5, 9};

struct PcfAccuracy {
  int width = 0;
  uint64_t samples = 0;     // lookups compared
  double meanAbsError = 0;  // mean |lookup - exact footprint fraction|
  double p99AbsError = 0;   // 99th percentile of the same
  double nsPerQuery = 0;    // batched lookup time
};

/// One structure at one resolution.
struct AccuracyRow {
  AccuracyMethod method = AccuracyMethod::Cpvs;
  int log2Resolution = 0;
  bool skipped = false;
  std::string note;                           // why skipped, or how it shares data with another row
  uint64_t side = 0;                          // texels a side (R for the CPVS)
  uint64_t bytes = 0;                         // DAG (or DAG-MH) bytes, or side^2 x 2
  double bakeSeconds = 0;                     // CPVS, DAG-MH: whole bake; shadow map: its rendering
  std::map<std::string, double> stageSeconds; // CPVS: per bake stage
  uint64_t samples = 0;                       // binary lookups compared
  uint64_t skippedInside = 0;                 // query point inside closed geometry: not compared
  uint64_t mismatches = 0;
  std::array<uint64_t, kDistanceBins> binSamples{}, binMismatches{};
  std::array<PcfAccuracy, kAccuracyPcfWidths.size()> pcf{};      // against texel-centre rays
  std::array<PcfAccuracy, kAccuracyPcfWidths.size()> pcfArea{};  // against the area average
  double nsPerQuery = 0;                      // binary batched lookup time

  uint64_t resolution() const { return uint64_t(1) << log2Resolution; }
  /// Bytes of a 16-bit shadow map of R^2 texels over these bytes.
  double ratioToShadowMap() const { return bytes ? double(resolution() * resolution() * 2) / double(bytes) : 0; }
  double mismatchRate() const { return samples ? double(mismatches) / double(samples) : 0; }
  /// Mismatch rate within a distance bin; NaN when the bin holds no sample.
  double binRate(int bin) const;
};

struct AccuracyOptions {
  std::vector<int> log2Resolutions{10, 11, 12};
  uint64_t samples = 100000;      // surface points, the same for every resolution and method
  /// Where the points lie: empty = uniform by area over every surface (sampleSurfaces);
  /// otherwise on what these cameras see (sampleCameraViews, images of cameraAspect).
  std::vector<Camera> cameras;
  double cameraAspect = 16.0 / 9.0;
  uint64_t pcfSamples = 10000;    // the first this many of them get PCF references
  uint64_t seed = 1;
  BakeOptions bake;
  /// Who the CPVS is baked for (bake.receivers and bake.receiverPcf follow it). Without
  /// cameras the points are where they are (sampleReceivers); with cameras, what the
  /// cameras see, declared or not.
  ReceiverDeclaration receivers;
  uint64_t maxFullShadowMapBytes = uint64_t(2) << 30;  // a full-resolution map above this is skipped
  double minTimingSeconds = 0.2;  // each lookup timing repeats the batch at least this long
};

struct AccuracyReport {
  std::string scene;
  uint64_t triangles = 0;
  Vec3 lightDir;
  uint64_t samples = 0, pcfSamples = 0, seed = 1;
  std::vector<Camera> cameras;  // empty: the points are uniform by area
  ReceiverKind receivers = ReceiverKind::Everywhere;  // the CPVS's declaration
  int receiverPcf = 0;
  double extent = 0, depthExtent = 0;  // the grid's u, v side and depth range (world units)
  double firstRadius = 0, maxRadius = 0;  // boundaryDistance's r0 and rMax
  unsigned threads = 0;                   // worker threads used for timings
  double timingSeconds = 0;               // each lookup timing ran at least this long
  std::vector<AccuracyRow> rows;          // per resolution, one per AccuracyMethod in order
  double seconds = 0;                     // the whole measurement
};

/// Bakes the scene at each resolution (bakeGrid, timed per stage; bakeDagMh), renders the
/// shadow-map baselines, and measures every structure on the same `samples` surface points
/// (sampleSurfaces: uniform by area, the side a lookup is made from; or sampleCameraViews
/// when options.cameras are given: what they see, the side they see):
///  - binary: the lookup from the point with its normal against exactlyLit at the point it
///    looks up (its offset point), binned by boundaryDistance of that point (with the
///    sample's normal), radii r0 = extent / (16 Rmax) doubling up to extent / 16;
///  - PCF 3, 5, 9 on the first pcfSamples points: |lookup - exactFootprintLit| over the
///    lookup's own footprint and offset point, with texel-centre rays (pcf) and with
///    kAreaRaysPerTexelSide^2 rays per texel (pcfArea);
///  - ns per batched lookup (binary and each PCF width), all threads.
/// Query points inside closed geometry are skipped and counted. Progress gets stages
/// named "<R> bake", "<R> shadow maps", "<R> exact", "<R> pcf", "<R> timing"; Cancelled
/// is thrown when it returns false. InputError for an empty resolution list, samples < 1,
/// or cameras that see no surface.
AccuracyReport measureAccuracy(const Scene& scene, const LightFrame& frame, const AccuracyOptions& options,
                               const ProgressFn& progress = nullptr);

}  // namespace cpvs
