// Points on a scene's surfaces to measure at: uniformly by area, or as cameras see them.
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/bake/receivers.h"
#include "cpvs/eval/camera.h"
#include "cpvs/light/perspective_grid.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

/// A point on a surface with the normal of the side a lookup is made from.
struct SurfaceSample {
  Vec3 point, normal;
};

/// `count` points sampled uniformly by area over the scene's triangles (deterministic for
/// a seed). The normal is the outward one for closed geometry, and for open geometry the
/// side facing the light (`lightDir` points from the light into the scene).
std::vector<SurfaceSample> sampleSurfaces(const Scene& scene, const RayScene& rays, ClosedMode closed,
                                          const Vec3& lightDir, uint64_t count, uint64_t seed);

/// Up to `count` points sampled uniformly by area over the surfaces inside a spot light's
/// cone (half-angle atan(tanCone)), deterministic for a seed: sample i is drawn up to
/// kConeSampleAttempts times from the triangles that may reach into the cone, dropped
/// when none lands inside it. Normals as sampleSurfaces, open geometry's facing the light.
/// With `sides` (receivingSides: bit 0 the front, bit 1 the back), only receiving sides:
/// an open triangle's other side where the one facing the light does not receive.
std::vector<SurfaceSample> sampleSpotSurfaces(const Scene& scene, const RayScene& rays, ClosedMode closed,
                                              const PerspectiveGrid& grid, double tanCone, uint64_t count,
                                              uint64_t seed, const std::vector<uint8_t>* sides = nullptr);
constexpr int kConeSampleAttempts = 64;

/// `count` points where the declared receivers are, deterministic for a seed: for
/// Everywhere, sampleSurfaces; for Surfaces, uniformly by area with the front side's
/// normal; for SurfacesTwoSided, either side of open triangles (the outside of closed
/// ones); for Volume, half as Surfaces and half uniformly inside the volume (its meshes,
/// and its ground layer: a point of a walkable triangle by area, raised uniformly between
/// the layer's bottom and top; with both, every other point in each) with random unit normals (every
/// 8th without one).
std::vector<SurfaceSample> sampleReceivers(const Scene& scene, const RayScene& rays, ClosedMode closed,
                                           const Vec3& lightDir, const ReceiverDeclaration& receivers,
                                           uint64_t count, uint64_t seed);

/// Rays a camera sample may spend on sky before its point is dropped.
constexpr int kCameraSampleAttempts = 16;

/// Up to `count` points of the surfaces the cameras see, each with the normal of the side
/// seen: sample i is the first hit of a ray through a uniformly random point of the image
/// (of width / height `aspect`) of camera i mod cameras.size(), drawn again up to
/// kCameraSampleAttempts times while it sees nothing, dropped after that. Deterministic
/// for a seed (whatever the threads). Points are spread as the images' pixels are: dense
/// where a camera looks closely, as a player's view is.
std::vector<SurfaceSample> sampleCameraViews(const Scene& scene, const RayScene& rays,
                                             const std::vector<Camera>& cameras, double aspect, uint64_t count,
                                             uint64_t seed);

}  // namespace cpvs
