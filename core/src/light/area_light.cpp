#include "cpvs/light/area_light.h"

#include <cmath>
#include <string>

#include "cpvs/base/error.h"
#include "cpvs/base/parse.h"
#include "cpvs/base/split_mix64.h"

namespace cpvs {

namespace {

// The radical inverse of i in `base`: the Halton sequence's coordinate.
double radicalInverse(uint32_t i, uint32_t base) {
  double inverse = 1.0 / base, f = inverse, r = 0;
  for (; i > 0; i /= base, f *= inverse) r += f * double(i % base);
  return r;
}

// VPL i's cube: one face looking along the emitter's normal (where its light is
// strongest and cos-weighted lookups gather, that face sees the receivers head on, as a
// spot light would), turned about the normal by a seeded angle and tilted by a seeded
// fraction of a texel about the other two axes, so that the VPLs' texels fall at unrelated
// angles and sub-texel phases (seed 002's decorrelated frames). Only exact operations and
// sqrt: every machine turns the cube alike.
std::array<Vec3, 3> rolledCube(const Vec3& normal, int log2Resolution, SplitMix64& rng) {
  const LightFrame f = LightFrame::fromDirection(normal);
  double cx, cy, r2;  // a direction in the emitter's plane, uniform in angle
  do {
    cx = 2 * rng.uniform01() - 1;
    cy = 2 * rng.uniform01() - 1;
    r2 = cx * cx + cy * cy;
  } while (!(r2 > 1e-6 && r2 <= 1));
  const Vec3 a0 = normalize(f.u * cx + f.v * cy), a1 = -f.dir, a2 = cross(a0, a1);
  // The tilt: a rotation by up to half a texel's angle (1/R radians at a face's centre)
  // either way about a0 and a2, as the quaternion (1, jx, 0, jz), half-angles jx, jz.
  const double half = 0.5 / double(uint64_t(1) << log2Resolution);
  const double jx = (2 * rng.uniform01() - 1) * half, jz = (2 * rng.uniform01() - 1) * half;
  const double inv = 1 / std::sqrt(1 + jx * jx + jz * jz);
  const double w = inv, x = jx * inv, z = jz * inv;
  // The rotation's columns in the cube's frame (a unit quaternion's matrix, y = 0).
  const Vec3 c0{1 - 2 * z * z, 2 * w * z, 2 * x * z}, c1{-2 * w * z, 1 - 2 * (x * x + z * z), 2 * w * x},
      c2{2 * x * z, -2 * w * x, 1 - 2 * x * x};
  auto inCube = [&](const Vec3& c) { return withoutNegativeZeros(a0 * c.x + a1 * c.y + a2 * c.z); };
  return {inCube(c0), inCube(c1), inCube(c2)};
}

}  // namespace

void checkAreaLight(const AreaLight& a, const Vec3& lo, const Vec3& hi, const std::string& source) {
  auto fail = [&](const std::string& what) { throw InputError(source + ": " + what); };
  if (!isFinite(a.centre) || !isFinite(a.edgeU) || !isFinite(a.edgeV)) fail("the centre and edges must be finite");
  const double area = length(cross(a.edgeU, a.edgeV));
  if (!(area > 1e-12 * dot(a.edgeU, a.edgeU)) || !(area > 1e-12 * dot(a.edgeV, a.edgeV)))
    fail("the edges are zero or parallel: the rectangle has no area");
  if (a.vpls < 1 || a.vpls > kMaxVpls)
    fail(std::to_string(a.vpls) + " VPLs: an area light takes 1 to " + std::to_string(kMaxVpls));
  if (a.log2Resolution < kMinVplLog2Resolution || a.log2Resolution > kMaxVplLog2Resolution)
    fail("VPL resolution 2^" + std::to_string(a.log2Resolution) + " is outside 2^" +
         std::to_string(kMinVplLog2Resolution) + " to 2^" + std::to_string(kMaxVplLog2Resolution));
  // Each VPL is a point light: checkLight says the rest (bounds, range, colour).
  Light l;
  l.kind = LightKind::Point;
  l.position = a.centre;
  l.range = a.range;
  l.colour = a.colour;
  l.intensity = a.intensity;
  checkLight(l, lo, hi, source);
}

AreaLight parseAreaLightFlag(const std::string& text) {
  const std::vector<std::string> parts = splitAt(text, ':');
  auto bad = [&](const std::string& why) {
    return InputError("--area-light '" + text + "': " + why +
                      " (expected CX,CY,CZ:UX,UY,UZ:VX,VY,VZ[:K[:RES]], the centre, the two edges, the VPL count and "
                      "their resolution)");
  };
  if (parts.size() < 3 || parts.size() > 5) throw bad("3 to 5 fields");
  AreaLight a;
  a.centre = parseVec3(parts[0], "--area-light's centre");
  a.edgeU = parseVec3(parts[1], "--area-light's edge U");
  a.edgeV = parseVec3(parts[2], "--area-light's edge V");
  if (parts.size() > 3) {
    const std::vector<double> k = parseNumbers(parts[3], "--area-light's VPL count");
    if (k.size() != 1 || k[0] < 1 || k[0] > kMaxVpls || k[0] != std::floor(k[0]))
      throw bad("the VPL count must be a whole number from 1 to " + std::to_string(kMaxVpls));
    a.vpls = uint32_t(k[0]);
  }
  if (parts.size() > 4) {
    a.log2Resolution = parseResolution(parts[4]);
    if (a.log2Resolution < kMinVplLog2Resolution || a.log2Resolution > kMaxVplLog2Resolution)
      throw bad("the VPL resolution must be 16 to 1024");
  }
  return a;
}

std::vector<Light> vplsOf(const AreaLight& a, uint32_t areaNumber) {
  const Vec3 n = a.normal();
  SplitMix64 rng(a.seed ^ 0xA5EA11647ull);
  const double su = rng.uniform01(), sv = rng.uniform01();  // the Cranley-Patterson rotation
  const double lift = 1e-4 * (length(a.edgeU) + length(a.edgeV));
  std::vector<Light> out;
  for (uint32_t i = 0; i < a.vpls; ++i) {
    const double s = std::fmod(radicalInverse(i + 1, 2) + su, 1.0), t = std::fmod(radicalInverse(i + 1, 3) + sv, 1.0);
    Light l;
    l.kind = LightKind::Point;
    l.name = (a.name.empty() ? "area " + std::to_string(areaNumber) : a.name) + " vpl " + std::to_string(i);
    l.position = a.centre + a.edgeU * (s - 0.5) + a.edgeV * (t - 0.5) + n * lift;
    l.direction = n;
    l.range = a.range;
    l.colour = a.colour;
    l.intensity = a.intensity / double(a.vpls);
    l.log2Resolution = a.log2Resolution;
    l.area = areaNumber;
    if (a.roll) {
      SplitMix64 turn = SplitMix64::forItem(a.seed ^ 0x70117u, i);
      l.cube = rolledCube(n, a.log2Resolution, turn);
    }
    out.push_back(std::move(l));
  }
  return out;
}

std::vector<Light> vplsOf(const std::vector<AreaLight>& areas) {
  std::vector<Light> out;
  for (size_t k = 0; k < areas.size(); ++k)
    for (Light& l : vplsOf(areas[k], uint32_t(k + 1))) out.push_back(std::move(l));
  return out;
}

double vplWeight(const Vec3& x, const Vec3& emitterNormal, const Vec3& p, const Vec3& n) {
  const Vec3 d = p - x;
  const double d2 = dot(d, d);
  if (!(d2 > 0)) return 0;
  const double dist = std::sqrt(d2);
  const double cosEmitter = dot(emitterNormal, d) / (length(emitterNormal) * dist);
  if (!(cosEmitter > 0)) return 0;
  double cosReceiver = 1;
  if (!(n == Vec3{})) {
    cosReceiver = -dot(n, d) / (length(n) * dist);
    if (!(cosReceiver > 0)) return 0;
  }
  return cosEmitter * cosReceiver / d2;
}

}  // namespace cpvs
