// What a bake will compute and why (the effect planner): the closed parts found, the
// receiver declaration and what it leaves free, the lights the scene file holds and
// which of them are baked, and which passes run. Deterministic: a function of the scene,
// the grid, the options and the declaration, so the local bake and the farm record the
// same plan in the artifact.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/bake/raster_scene.h"
#include "cpvs/bake/receivers.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

/// Cells per side of a plan's receiver coverage (fewer when R is smaller).
constexpr uint32_t kPlanCoverageCells = 64;
/// log2 of the grid side at which a plan counts the columns receivers reach.
constexpr int kLog2PlanColumns = 12;

struct BakePlan {
  std::string scene;
  uint64_t triangles = 0, parts = 0, closedParts = 0, closedTriangles = 0;
  double closedAreaShare = 0;  // of the scene's surface area, in closed parts
  uint64_t resolution = 0;
  uint64_t depthSlices = 0;  // the grid's (OrthoGrid::depthSlices; 0: cubic), for the text only
  ReceiverKind receivers = ReceiverKind::Everywhere;
  int receiverPcf = 0;                 // 0 for everywhere
  uint64_t tiles = 0;
  uint64_t tilesUntouched = 0;         // no triangle can touch them: all lit, not rendered
  uint64_t tilesUnread = 0;            // touched, but no declared receiver reads them: not rendered either
  enum TileClass : uint8_t { kUntouched, kUnread, kRendered };
  std::vector<uint8_t> tileClasses;    // a TileClass per tile, in TilePlan order (y * per side + x)
  double columnsReadShare = 1;         // texel columns some receiver's lookups reach (1 for everywhere)
  uint64_t columnsSampledSide = 0;     // the grid side that share was counted at (min(R, 4096))
  // Where declared receivers may read: coverageCells^2 cells of R / coverageCells texels
  // square, row by row (texel y, then x); 1 where some receiver's lookup may read a
  // column of the cell (by its bounding box: a superset), 0 where none can. Empty for
  // everywhere. Recorded in artifacts, so that a lookup can tell it is outside.
  uint32_t coverageCells = 0;
  std::vector<uint8_t> coverage;
  // The declaration's ground layer (height 0: none) and the walkable triangles it covers.
  double groundLayerFrom = 0, groundLayer = 0, groundSlopeDeg = 0;
  uint64_t walkableTriangles = 0;
  double walkableAreaShare = 0;  // of the scene's surface area
  // The surfaces that receive (receivingSides; not for everywhere): their sides (a triangle
  // receiving on both counts twice) and those sides' area over the scene's surface area
  // (so above 1 when many triangles receive on both sides).
  uint64_t receivingSides = 0;
  double receivingAreaShare = 0;
  // Cameras: how the sides they see were found and, sampled, the positions and rays cast.
  bool cameras = false;
  CameraVisibility cameraVisibility = CameraVisibility::Faced;
  uint64_t cameraPositions = 0, cameraRays = 0;
  struct Light {
    SceneLight light;
    bool baked = false;
    std::string reason;
  };
  std::vector<Light> lights;
  // Participating media: the job's (source "declared") and the scene's volumes (source
  // "KHR_materials_volume"), and whether this bake's voxels answer light along segments
  // through them. Nothing is baked for them: a sun's grid holds the air already.
  struct Medium {
    std::string name, source;
    double scattering = 0, absorption = 0, g = 0;
    bool offered = false;
    std::string reason;
  };
  std::vector<Medium> media;
  // Translucent meshes (isTranslucent): left out of the CPVS, their shadow frusta a TOP
  // tree beside it (translucentTree). Recorded in the JSON only when there are some, so
  // that an opaque scene's artifact keeps its bytes.
  uint64_t translucentMeshes = 0, translucentTriangles = 0;
  struct Pass {
    std::string name;
    bool runs = false;
    std::string why;
  };
  std::vector<Pass> passes;
};

/// The plan of baking `scene` (with `stats` from its import) on `raster`'s grid with
/// `options` for `receivers` (`raster`: the sun's casters, sunCasters; `reads`: the
/// receivers' projection on that grid; as BakeScene holds both). Projects the receivers once more at min(R, 4096) to count the columns they
/// reach (a fraction of a second on large scenes).
/// `media`: the job's declared media (name, source and coefficients; the plan says whether
/// they are offered), before the scene's own.
BakePlan planBake(const Scene& scene, const SceneStats& stats, const BakeOptions& options,
                  const ReceiverDeclaration& receivers, const RasterScene& raster, const ReceiverSet& reads,
                  std::vector<BakePlan::Medium> media = {});

/// The plan as one JSON object (what artifacts record and `cpvs plan --json` prints); the
/// scene's name is left out (a copy of the file bakes to the same bytes).
std::string planJson(const BakePlan& plan);
/// The plan for people, one line per fact.
std::string planText(const BakePlan& plan);

/// The receiver coverage a plan's JSON records (planJson's "coverage") for a grid of
/// `resolution`, into `cells` and `coverage` as BakePlan holds them; false (both cleared)
/// when it records none (a bake for everywhere, a file from before coverage was recorded)
/// or holds anything else (cells other than min(kPlanCoverageCells, resolution) included).
bool planCoverage(const std::string& planJson, uint64_t resolution, uint32_t& cells, std::vector<uint8_t>& coverage);

}  // namespace cpvs
