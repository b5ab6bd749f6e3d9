// The frame of a directional light.
#pragma once

#include "cpvs/base/vec3.h"

namespace cpvs {

/// Orthonormal frame (u, v, dir) of a directional light; `dir` points from the light into
/// the scene. Built without a branch on the direction (Duff et al. 2017), so axis-aligned,
/// almost axis-aligned and grazing directions all get an exactly orthonormal frame.
struct LightFrame {
  Vec3 dir, u, v;

  bool operator==(const LightFrame&) const = default;

  /// `d` need not be normalized; throws InputError when it is not finite or is zero.
  static LightFrame fromDirection(const Vec3& d);
  /// Sun given by elevation above the horizon (Y is up) and azimuth (degrees, 0 = the sun
  /// stands towards +Z, 90 = towards +X). Throws InputError for an elevation below 0 or
  /// above 90, or non-finite angles.
  static LightFrame fromElevationAzimuth(double elevationDeg, double azimuthDeg);
};

/// How far a stored light direction may be from unit length (readers of files and of
/// the farm's messages accept the same).
constexpr double kUnitDirectionTolerance = 1e-9;

}  // namespace cpvs
