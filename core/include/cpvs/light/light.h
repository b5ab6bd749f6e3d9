// A local light as a lighting artist describes it (seed 000 §5): a spot light or a point
// light, where it is, where it points, how far it reaches, and what its shading needs.
// What the planner turns into perspective grids (light_plan.h).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "cpvs/base/vec3.h"
#include "cpvs/light/frame.h"

namespace cpvs {

enum class LightKind : uint8_t {
  Spot = 0,   // one perspective grid around its cone
  Point = 1,  // six 90-degree perspective grids, a cube's faces
};
const char* lightKindName(LightKind kind);

/// The widest spot cone, half-angle in degrees (PerspectiveGrid's widest frustum).
constexpr double kMaxConeDeg = 85;
/// The most lights one bake takes.
constexpr size_t kMaxLights = 4096;
/// How far outside the scene's bounding box a light may be, in its diagonal.
constexpr double kLightBoundsMargin = 0.1;
/// The most fixture names (Light::exclude) one light takes, and the longest, in bytes.
constexpr size_t kMaxExcludeNames = 64;
constexpr size_t kMaxExcludeNameBytes = 1024;

struct Light {
  LightKind kind = LightKind::Spot;
  std::string name;
  Vec3 position;
  Vec3 direction{0, -1, 0};  // a spot light's axis (need not be unit length)
  double coneDeg = 45;       // a spot light's half-angle, degrees in (0, kMaxConeDeg]
  double range = 0;          // how far its light reaches (its grids' far); 0: the scene's far side
  Vec3 colour{1, 1, 1};      // linear RGB, for shading only
  double intensity = 1;      // for shading only
  double near = 0;           // its grids' near; 0: planned from the closest geometry
  int log2Resolution = 0;    // its grids' resolution; 0: planned from the footprint
  /// Its fixture: the meshes (by node, mesh or material name, meshIsNamed) that cast no
  /// shadow of this light. The lamp's glass and housing would otherwise darken all it lights.
  std::vector<std::string> exclude;
  /// A VPL of the bundle's area light number `area` (1-based, area_light.h): a point
  /// light whose direction is the emitter's normal. 0: a light of its own.
  uint32_t area = 0;
  /// A point light's cube: its faces look along +-cube[0], +-cube[1], +-cube[2] (an
  /// orthonormal basis). The world's axes unless rolled: an area light's VPLs each turn
  /// theirs by a seeded rotation, so that their voxels' errors do not line up.
  std::array<Vec3, 3> cube{Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}};
};

/// The world's axes: a cube that is not rolled.
constexpr std::array<Vec3, 3> kAxisCube{Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}};

/// A point light's cube: face f looks along cubeFaceAxis(f), in the order +x, -x, +y, -y,
/// +z, -z (of the cube's own axes, Light::cube).
Vec3 cubeFaceAxis(int face);
/// The face a direction from the light falls in: its largest axis (a tie goes to the
/// first of them; on an edge of the cube both faces answer).
int cubeFace(const Vec3& fromLight);
/// The same in a cube turned to `cube`: the direction's components along its axes, each a
/// dot product summed left to right as the GLSL include does (cpvsLightGrid), so that CPU
/// and GPU pick the same face. With kAxisCube it is cubeFace(fromLight).
int cubeFace(const Vec3& fromLight, const std::array<Vec3, 3>& cube);
/// Face f's frame in a cube turned to `cube`: the world-axis face's frame
/// (LightFrame::fromDirection(cubeFaceAxis(f))) rotated by it, so that the faces' squares
/// meet edge to edge whatever the rotation.
LightFrame cubeFaceFrame(int face, const std::array<Vec3, 3>& cube);
/// Whether `cube` is an orthonormal basis within kUnitDirectionTolerance.
bool isOrthonormalCube(const std::array<Vec3, 3>& cube);

/// InputError naming `source` ("light 3 (lamp)") and what is wrong: a position that is
/// not finite or lies outside the scene's bounds [lo, hi] grown by kLightBoundsMargin of
/// their diagonal, a spot direction that is zero, a cone outside (0, kMaxConeDeg], a
/// negative or non-finite range, near or intensity, a near not below the range, a
/// colour that is negative, a resolution out of range, or more than kMaxExcludeNames
/// fixture names, an empty one or one longer than kMaxExcludeNameBytes.
void checkLight(const Light& light, const Vec3& lo, const Vec3& hi, const std::string& source);
/// InputError unless 1 <= count <= kMaxLights.
void checkLightCount(size_t count);
/// "light 3" or "light 3 (lamp)": how errors and listings name light `index`.
std::string lightLabel(const Light& light, size_t index);

/// A spot light from the command line: "X,Y,Z:DX,DY,DZ:CONE[:RANGE]" (position, axis, the
/// half-angle in degrees, the reach); InputError naming the flag otherwise.
Light parseSpotFlag(const std::string& text);
/// A point light from the command line: "X,Y,Z[:RANGE]".
Light parsePointFlag(const std::string& text);

}  // namespace cpvs
