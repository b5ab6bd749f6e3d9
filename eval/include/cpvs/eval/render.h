// Pictures of a scene lit by the sun, with CPVS shadows or exact ray-traced ones, and the
// difference between the two: how a person checks a bake by eye.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cpvs/eval/image.h"
#include "cpvs/query/shadow_query.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/scene/source.h"
#include "cpvs/eval/verify.h"

namespace cpvs {

/// A pinhole camera; `fovDeg` is the vertical field of view.
struct Camera {
  Vec3 eye, target, up{0, 1, 0};
  double fovDeg = 40;

  /// Parses "EX,EY,EZ,TX,TY,TZ" or "EX,EY,EZ,TX,TY,TZ,FOV"; InputError otherwise.
  static Camera parse(const std::string& text);
};

/// A three-quarter view of the whole scene from its sunny side, Y up.
Camera defaultCamera(const Scene& scene, const Vec3& lightDir, double aspect);

/// What the camera sees through each pixel.
struct SurfaceHit {
  bool hit = false;
  Vec3 point;   // world position
  Vec3 normal;  // unit geometric normal, turned towards the camera
};
struct CameraHits {
  int width = 0, height = 0;
  std::vector<SurfaceHit> pixels;  // row-major, top row first
};

/// Traces one primary ray per pixel centre, multithreaded.
CameraHits traceCamera(const Scene& scene, const RayScene& rays, const Camera& camera, int width, int height);

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

/// Visibility of the sun per pixel (1 lit, 0 shadowed, fractions with PCF) from the CPVS,
/// with the lookup's normal offset; pixels without a hit get 1.
std::vector<float> cpvsVisibility(const CameraHits& hits, const ShadowQuery& query, int pcf);
/// The same from exact Embree shadow rays leaving the surface itself (a tiny offset
/// against self-intersection, no voxel bias): the ground truth a viewer compares with.
std::vector<float> exactVisibility(const CameraHits& hits, const RayScene& rays, const OrthoGrid& grid);

/// Shades the hits: grey surfaces under sky light plus the sun times visibility; a sky
/// gradient where nothing was hit. Linear values.
Image shadeHits(const CameraHits& hits, const std::vector<float>& visibility, const Vec3& lightDir);

/// Where two visibilities disagree on a surface facing the sun: red where `a` is darker,
/// blue where it is brighter, the scene in dim grey elsewhere. Counts the sunlit-facing
/// pixels compared and those that differ by more than half.
Image differenceImage(const CameraHits& hits, const std::vector<float>& a, const std::vector<float>& b,
                      const Vec3& lightDir, uint64_t* compared, uint64_t* differing);

}  // namespace cpvs
