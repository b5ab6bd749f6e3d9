#include "cpvs/query/medium.h"

#include <cmath>
#include <numbers>

#include "cpvs/base/error.h"
#include "cpvs/base/parse.h"

namespace cpvs {

void checkMedium(const Medium& m) {
  auto coefficient = [](double v, const char* name) {
    if (!std::isfinite(v) || v < 0)
      throw InputError(std::string("the medium's ") + name + " coefficient must be finite and not negative, got " +
                       std::to_string(v));
  };
  coefficient(m.scattering, "scattering");
  coefficient(m.absorption, "absorption");
  if (!std::isfinite(m.g) || m.g <= -1 || m.g >= 1)
    throw InputError("the medium's phase asymmetry g must lie strictly between -1 and 1, got " + std::to_string(m.g));
}

Medium parseMedium(const std::string& text, const std::string& what) {
  const std::vector<double> v = parseNumbers(text, what);
  if (v.size() != 2 && v.size() != 3)
    throw InputError(what + " '" + text + "': expected SIGMA_S,SIGMA_A or SIGMA_S,SIGMA_A,G (per world unit)");
  Medium m{v[0], v[1], v.size() == 3 ? v[2] : 0.0};
  try {
    checkMedium(m);
  } catch (const InputError& e) {
    throw InputError(what + " '" + text + "': " + e.what());
  }
  return m;
}

double henyeyGreenstein(double g, double cosTheta) {
  const double denom = 1 + g * g - 2 * g * cosTheta;
  return (1 - g * g) / (4 * std::numbers::pi * denom * std::sqrt(denom));
}

double attenuatedLength(double sigma, double u0, double u1) {
  if (sigma == 0) return u1 - u0;
  // e^(-s u0) - e^(-s u1) = -e^(-s u0) expm1(-s (u1 - u0)): no cancellation for small s.
  return -std::exp(-sigma * u0) * std::expm1(-sigma * (u1 - u0)) / sigma;
}

SegmentLight scatterAlong(const std::vector<std::pair<double, double>>& lit, double length, const Medium& m,
                          double cosTheta) {
  checkMedium(m);
  SegmentLight s;
  s.length = length;
  s.transmittance = std::exp(-m.extinction() * length);
  double attenuated = 0;
  for (const auto& [u0, u1] : lit) {
    s.litLength += u1 - u0;
    attenuated += attenuatedLength(m.extinction(), u0, u1);
  }
  s.inScattering = m.scattering * henyeyGreenstein(m.g, cosTheta) * attenuated;
  return s;
}

}  // namespace cpvs
