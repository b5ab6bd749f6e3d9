#include "cpvs/light/light.h"

#include <cmath>

#include "cpvs/base/error.h"
#include "cpvs/base/limits.h"
#include "cpvs/base/parse.h"

namespace cpvs {

const char* lightKindName(LightKind kind) { return kind == LightKind::Spot ? "spot" : "point"; }

Vec3 cubeFaceAxis(int face) {
  Vec3 a{};
  (face / 2 == 0 ? a.x : face / 2 == 1 ? a.y : a.z) = face % 2 == 0 ? 1 : -1;
  return a;
}

int cubeFace(const Vec3& d) {
  const double ax = std::abs(d.x), ay = std::abs(d.y), az = std::abs(d.z);
  if (ax >= ay && ax >= az) return d.x >= 0 ? 0 : 1;
  if (ay >= az) return d.y >= 0 ? 2 : 3;
  return d.z >= 0 ? 4 : 5;
}

int cubeFace(const Vec3& d, const std::array<Vec3, 3>& cube) {
  return cubeFace({dot(d, cube[0]), dot(d, cube[1]), dot(d, cube[2])});
}

LightFrame cubeFaceFrame(int face, const std::array<Vec3, 3>& cube) {
  const LightFrame axis = LightFrame::fromDirection(cubeFaceAxis(face));
  if (cube == kAxisCube) return axis;
  auto turn = [&](const Vec3& a) { return withoutNegativeZeros(cube[0] * a.x + cube[1] * a.y + cube[2] * a.z); };
  return {turn(axis.dir), turn(axis.u), turn(axis.v)};
}

bool isOrthonormalCube(const std::array<Vec3, 3>& c) {
  for (int i = 0; i < 3; ++i) {
    if (!isFinite(c[i]) || !(std::abs(dot(c[i], c[i]) - 1) <= kUnitDirectionTolerance)) return false;
    for (int j = 0; j < i; ++j)
      if (!(std::abs(dot(c[i], c[j])) <= kUnitDirectionTolerance)) return false;
  }
  return true;
}

std::string lightLabel(const Light& light, size_t index) {
  return "light " + std::to_string(index) + (light.name.empty() ? "" : " (" + light.name + ")");
}

void checkLightCount(size_t count) {
  if (count == 0) throw InputError("no lights: a bake of local lights needs at least one");
  if (count > kMaxLights)
    throw InputError(std::to_string(count) + " lights: a bake takes at most " + std::to_string(kMaxLights));
}

void checkLight(const Light& l, const Vec3& lo, const Vec3& hi, const std::string& source) {
  auto fail = [&](const std::string& what) { throw InputError(source + ": " + what); };
  if (!isFinite(l.position)) fail("the position is not finite");
  const double margin = kLightBoundsMargin * length(hi - lo);
  const Vec3& p = l.position;
  if (p.x < lo.x - margin || p.y < lo.y - margin || p.z < lo.z - margin || p.x > hi.x + margin ||
      p.y > hi.y + margin || p.z > hi.z + margin)
    fail("the position (" + std::to_string(p.x) + ", " + std::to_string(p.y) + ", " + std::to_string(p.z) +
         ") is outside the scene's bounds (" + std::to_string(lo.x) + ", " + std::to_string(lo.y) + ", " +
         std::to_string(lo.z) + ") to (" + std::to_string(hi.x) + ", " + std::to_string(hi.y) + ", " +
         std::to_string(hi.z) + ")");
  if (l.kind == LightKind::Spot) {
    if (!isFinite(l.direction) || !(length(l.direction) > 0)) fail("the spot light's direction is zero or not finite");
    if (!(l.coneDeg > 0) || !(l.coneDeg <= kMaxConeDeg))
      fail("the cone's half-angle " + std::to_string(l.coneDeg) + " degrees is outside (0, " +
           std::to_string(int(kMaxConeDeg)) + "]");
  }
  if (l.area != 0 && (l.kind != LightKind::Point || !isFinite(l.direction) || !(length(l.direction) > 0)))
    fail("a VPL of an area light is a point light with the emitter's normal as its direction");
  if (l.kind == LightKind::Point && !isOrthonormalCube(l.cube)) fail("the point light's cube axes are not orthonormal");
  if (!std::isfinite(l.range) || l.range < 0) fail("the range must be 0 (to the scene's far side) or positive");
  if (!std::isfinite(l.near) || l.near < 0) fail("near must be 0 (planned) or positive");
  if (l.near > 0 && l.range > 0 && !(l.near < l.range))
    fail("near " + std::to_string(l.near) + " must be less than the range " + std::to_string(l.range));
  if (!isFinite(l.colour) || l.colour.x < 0 || l.colour.y < 0 || l.colour.z < 0) fail("the colour must be finite and not negative");
  if (!std::isfinite(l.intensity) || l.intensity < 0) fail("the intensity must be finite and not negative");
  if (l.log2Resolution != 0 && (l.log2Resolution < kMinLog2Resolution || l.log2Resolution > kMaxLog2Resolution))
    fail("resolution 2^" + std::to_string(l.log2Resolution) + " is out of range");
  if (l.exclude.size() > kMaxExcludeNames)
    fail(std::to_string(l.exclude.size()) + " fixture names: a light takes at most " + std::to_string(kMaxExcludeNames));
  for (const std::string& name : l.exclude)
    if (name.empty() || name.size() > kMaxExcludeNameBytes)
      fail("a fixture name must be 1 to " + std::to_string(kMaxExcludeNameBytes) + " bytes long");
}

namespace {

double number(const std::string& text, const std::string& what) {
  const std::vector<double> v = parseNumbers(text, what);
  if (v.size() != 1) throw InputError(what + ": expected one number, got \"" + text + "\"");
  return v[0];
}

}  // namespace

Light parseSpotFlag(const std::string& text) {
  const std::vector<std::string> f = splitAt(text, ':');
  if (f.size() < 3 || f.size() > 4)
    throw InputError("--spot \"" + text + "\": expected X,Y,Z:DX,DY,DZ:CONE[:RANGE] (position, axis, half-angle in degrees, reach)");
  Light l;
  l.kind = LightKind::Spot;
  l.position = parseVec3(f[0], "--spot position");
  l.direction = parseVec3(f[1], "--spot direction");
  l.coneDeg = number(f[2], "--spot cone");
  if (f.size() == 4) l.range = number(f[3], "--spot range");
  return l;
}

Light parsePointFlag(const std::string& text) {
  const std::vector<std::string> f = splitAt(text, ':');
  if (f.empty() || f.size() > 2) throw InputError("--point \"" + text + "\": expected X,Y,Z[:RANGE] (position, reach)");
  Light l;
  l.kind = LightKind::Point;
  l.position = parseVec3(f[0], "--point position");
  if (f.size() == 2) l.range = number(f[1], "--point range");
  return l;
}

}  // namespace cpvs
