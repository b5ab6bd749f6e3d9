#include "cpvs/light/frame.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "cpvs/base/error.h"


namespace cpvs {

LightFrame LightFrame::fromDirection(const Vec3& d) {
  if (!isFinite(d)) throw InputError("light direction is not finite");
  // Scaled by its largest component first, so that a direction of huge or tiny (even
  // subnormal) components normalizes without overflow or underflow.
  const double m = std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)});
  if (!(m > 0)) throw InputError("light direction is the zero vector");
  const Vec3 scaled = d / m;
  LightFrame f;
  // No negative zeros: -0 and +0 name one direction, and a frame is stored where the sign
  // of a zero does not survive (SQLite keeps 0.0 as the integer 0): the farm's grid must be
  // the local bake's bit for bit. Adding +0.0 turns -0.0 into +0.0 and changes nothing else.
  f.dir = withoutNegativeZeros(scaled / length(scaled));
  // Duff, Burgess, Christensen, Hery, Kensler, Liani, Villemin: "Building an Orthonormal
  // Basis, Revisited" (JCGT 2017). Continuous except at the sign flip, exact everywhere.
  const Vec3& n = f.dir;
  double sign = std::copysign(1.0, n.z);
  double a = -1.0 / (sign + n.z);
  double b = n.x * n.y * a;
  f.u = withoutNegativeZeros(Vec3(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x));
  f.v = withoutNegativeZeros(Vec3(b, sign + n.y * n.y * a, -n.y));
  return f;
}

LightFrame LightFrame::fromElevationAzimuth(double elevationDeg, double azimuthDeg) {
  if (!std::isfinite(elevationDeg) || !std::isfinite(azimuthDeg))
    throw InputError("sun elevation and azimuth must be finite numbers");
  if (elevationDeg < 0.0)
    throw InputError("sun elevation " + std::to_string(elevationDeg) +
                     " deg is below the horizon; give --sun-dir for a light from below");
  if (elevationDeg > 90.0)
    throw InputError("sun elevation " + std::to_string(elevationDeg) + " deg is above 90");
  double el = elevationDeg * std::numbers::pi / 180.0;
  double az = azimuthDeg * std::numbers::pi / 180.0;
  Vec3 towardsSun(std::cos(el) * std::sin(az), std::sin(el), std::cos(el) * std::cos(az));
  return fromDirection(-towardsSun);
}

}  // namespace cpvs
