// Helpers for tests on real and generated scenes: where the shared scenes are, and a
// brute-force (every ray against every triangle, in double precision) texel classifier.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "cpvs/bake/bake.h"
#include "cpvs/bake/texel_slices.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/light/frame.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/light/perspective_grid.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/scene/source.h"

namespace cpvs::testing {

/// The shared scene folder beside the project (present in CI), or "" when absent.
std::string sharedScenesDir();

/// A shared scene's path; skips the calling test with a message when the folder is absent.
#define CPVS_SHARED_SCENE_OR_SKIP(var, relative)                                                  \
  std::string var;                                                                                \
  do {                                                                                            \
    std::string dir_ = ::cpvs::testing::sharedScenesDir();                                        \
    if (dir_.empty()) GTEST_SKIP() << "shared/scenes is not beside the project: skipping " relative; \
    var = dir_ + "/" relative;                                                                    \
  } while (0)

/// Brute-force depths of one texel: the centre ray against every triangle in double
/// precision, classified by the same rule as the renderer. `ambiguous` is set when the
/// ray passes within a hair of a triangle's edge, or a hit lies within a hair of a slice
/// boundary: there float and double arithmetic may legitimately disagree.
void bruteForceTexel(const Scene& scene, const OrthoGrid& grid, ClosedMode closed, ExitMode exit, uint64_t x,
                            uint64_t y, uint32_t& lo, uint32_t& hi, bool& ambiguous);

/// The same for a texel of a spot light's grid (its ray from the light, slices of view
/// depth; a texel the cone misses is all undefined).
void bruteForceSpotTexel(const Scene& scene, const PerspectiveGrid& grid, double tanCone, ClosedMode closed,
                         ExitMode exit, uint64_t x, uint64_t y, uint32_t& lo, uint32_t& hi, bool& ambiguous);

/// A spot lamp placed in a scene by its bounding box: the cases of the spot light's tests.
struct LampCase {
  const char* name;
  const char* scene;  // a procedural scene, or a path under shared/scenes
  bool shared;
  Vec3 offset;  // the lamp, from the scene's bounding-box centre, in its extent
  Vec3 dir;
  double tanHalfFov, tanCone, near, far;  // near and far in the scene's diagonal
  int log2R;
};
/// Opens the case's scene and makes its lamp's grid; false when the scene is a shared one
/// and shared/scenes is not beside the project. `centre` is the scene's bounding-box centre.
bool openLamp(const LampCase& lamp, Scene& scene, Vec3& centre, std::optional<PerspectiveGrid>& grid);

/// Brute-force depths of the whole grid; `ambiguous` marks texels to leave out.
void bruteForceDepths(const Scene& scene, const OrthoGrid& grid, ClosedMode closed, ExitMode exit,
                             TexelSlices& out, std::vector<uint8_t>& ambiguous);

/// bakeGrid of the scene prepared for the options' renderer.
Dag bakeWith(const Scene& scene, const OrthoGrid& grid, const BakeOptions& options);
/// The artifact `cpvs bake` writes for the scene (its plan, scene and receiver hashes
/// included): what a farm's artifact of the same job must equal byte for byte.
CpvsArtifact localArtifact(const Scene& scene, const OrthoGrid& grid, BakeOptions options,
                           const ReceiverDeclaration& receivers = {});

/// Writes the scene as a self-contained binary glTF (.glb): a node and a mesh for each of
/// its meshes (one for all when it has none), positions in float, each translucent mesh's
/// material its transmittance exactly (a base colour of it, KHR_materials_transmission 1).
void writeGlb(const Scene& scene, const std::string& path);

/// A small city (city:3:5) with glass: two tinted panes in the air, partly one over the
/// other (light crosses both), and a closed glass box; finalized.
Scene glassCity();

/// Appends the quad a-b-c-d as two triangles, counter-clockwise seen from its front.
void appendQuad(Scene& scene, Vec3 a, Vec3 b, Vec3 c, Vec3 d);

/// bakeTile of the scene prepared for the options' renderer.
Dag bakeTileWith(const Scene& scene, const OrthoGrid& grid, uint64_t tileX, uint64_t tileY, const BakeOptions& options);

}  // namespace cpvs::testing
