// Sampled camera visibility (seed 004's receiver masks, computed once instead of per frame):
// the triangle sides that rays from sampled camera positions hit first, each taken whole.
// Not conservative between samples: a side seen only from between two positions, or only
// between two rays, is missed; `verify` measures how often with an independent sample.
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/bake/receivers.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

/// The most rays one sampled camera declaration may cast (positions x 6 x rays^2): about
/// half a minute of a 2-core coordinator's submit (which a client waits 60 s for) and of
/// each worker's first tile of the job; and the most positions.
constexpr uint64_t kMaxCameraSampleRays = uint64_t(1) << 27;
constexpr uint64_t kMaxCameraPositions = uint64_t(1) << 22;

/// Sampled camera visibility's default spacing of positions, as a share of the view distance.
constexpr double kDefaultCameraSpacingShare = 1.0 / 16;

/// The spacing of sampled positions: the declared one, or the default share of the view
/// distance.
double cameraSpacing(const ReceiverDeclaration& declaration);

/// Rays per side of a cube face: the declared number, or kDefaultCameraRays.
uint32_t cameraRaysPerSide(const ReceiverDeclaration& declaration);

/// How many positions cameraPositions gives, without making them.
double cameraPositionCount(const ReceiverDeclaration& declaration);

/// InputError when a sampled camera declaration has more than kMaxCameraPositions
/// positions or casts more than kMaxCameraSampleRays rays (the message says what to raise
/// or lower); nothing for any other declaration. checkReceiverDeclaration calls it.
void checkCameraBudget(const ReceiverDeclaration& declaration);

/// Where cameras are sampled: each region's grid of positions at most cameraSpacing apart
/// along each axis (its corners included), each point, each path's vertices and positions
/// at most cameraSpacing apart along its segments. Seed 0: exactly those; another seed: an
/// independent sample, each grid position moved by up to half a grid step along each axis
/// (within its region) and each path position by up to half a step along its segment;
/// points stay. InputError as checkCameraBudget.
std::vector<Vec3> cameraPositions(const ReceiverDeclaration& declaration, uint64_t seed = 0);

struct CameraViews {
  std::vector<uint8_t> sides;  // per scene triangle: bit 0 the front hit, bit 1 the back
  uint64_t positions = 0, rays = 0, hits = 0;
  // With `declared`: the hits on a side it does not hold, and the area of such sides.
  uint64_t hitsOutside = 0;
  double areaOutside = 0, areaDeclared = 0;
};

/// Casts, from every camera position, cameraRays^2 rays through each face of a cube (seed 0:
/// texel centres; another seed: a point drawn in each texel) up to the view distance, with
/// the exact caster: the result is the same on every machine and thread count. A side is
/// the front when the intersection's determinant says the ray meets the winding's side; a
/// closed part counts on its outside only. With `declared` (sides, as `sides`), also counts what
/// falls outside it: the rate at which another sample sees what a bake left free.
CameraViews sampleCameraViews(const Scene& scene, const ReceiverDeclaration& declaration, uint64_t seed = 0,
                              const std::vector<uint8_t>* declared = nullptr);

}  // namespace cpvs
