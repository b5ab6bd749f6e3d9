// A homogeneous participating medium (fog, haze) and the closed forms of single
// scattering of the sun along a view segment through it (seed 002 §2.1, NOTES §3.4).
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace cpvs {

/// Coefficients per world unit.
struct Medium {
  double scattering = 0;  // sigma_s
  double absorption = 0;  // sigma_a
  double g = 0;           // Henyey-Greenstein asymmetry: 0 isotropic, > 0 forward, in (-1, 1)
  double extinction() const { return scattering + absorption; }
};

/// InputError for negative or non-finite coefficients or g outside (-1, 1).
void checkMedium(const Medium& m);
/// "SIGMA_S,SIGMA_A[,G]", checked; InputError naming `what` otherwise.
Medium parseMedium(const std::string& text, const std::string& what);

/// The Henyey-Greenstein phase function (per steradian) for the cosine of the scattering
/// angle, the angle between the light's direction of travel and the scattered one.
double henyeyGreenstein(double g, double cosTheta);

/// The integral of e^(-sigma u) over u in [u0, u1]: the length of that stretch as the
/// medium attenuates it on its way to the segment's start. Exact and stable as sigma -> 0
/// (u1 - u0 at sigma = 0).
double attenuatedLength(double sigma, double u0, double u1);

/// Single scattering of the sun along a segment from the eye a to b.
struct SegmentLight {
  double length = 0;         // |b - a|
  double litLength = 0;      // how much of it the sun reaches
  double transmittance = 0;  // e^(-sigma |b - a|): what reaches a of the light leaving b
  /// The radiance scattered towards a per unit of sun irradiance:
  /// sigma_s p(theta) * sum over lit stretches [u0, u1] of the attenuated length, the sun's
  /// own extinction on its way in ignored.
  double inScattering = 0;
};

/// The single scattering along a segment of `length` through medium m (checked), from its
/// lit stretches (distances from its start), scattered by the angle whose cosine is given
/// (between the sun's direction of travel and the direction from b towards a).
SegmentLight scatterAlong(const std::vector<std::pair<double, double>>& lit, double length, const Medium& m,
                          double cosTheta);

}  // namespace cpvs
