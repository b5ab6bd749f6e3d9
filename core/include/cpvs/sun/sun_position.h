// Where the sun stands for a place on Earth and an instant: ERFA (the IAU SOFA library)
// for the sun's apparent place, the observer's parallax, refraction if asked for, and
// the direction of its light in a scene's axes, for a bake.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "cpvs/base/vec3.h"

namespace cpvs {

/// An instant in UTC (seconds may reach 60.999 inside a leap second).
struct UtcInstant {
  int year = 2000, month = 1, day = 1, hour = 0, minute = 0;
  double second = 0;
};

/// Parses ISO 8601 with a zone: YYYY-MM-DDTHH:MM[:SS[.fff]] followed by Z or ±HH:MM
/// (or ±HHMM); a space may stand for the T. Converted to UTC. InputError naming `what`
/// and the expected form for anything else, including a missing zone.
UtcInstant parseUtcInstant(const std::string& text, const std::string& what = "--time");
/// "2003-10-17T19:30:30Z" (fractional seconds when there are any).
std::string formatUtcInstant(const UtcInstant& t);
/// Milliseconds since 1970-01-01T00:00:00Z as Unix time counts them (no leap seconds),
/// and back: how instants are stored and stepped.
int64_t unixMillis(const UtcInstant& t);
UtcInstant utcFromUnixMillis(int64_t ms);

/// A place: geodetic latitude and longitude (degrees, north and east positive) and height
/// above the WGS84 ellipsoid (metres).
struct Place {
  double latitudeDeg = 0, longitudeDeg = 0, heightM = 0;
};

/// Refraction: none unless a pressure is given.
struct Atmosphere {
  double pressureMbar = 0;  // 0: no refraction
  double temperatureC = 10;
};

/// The scene's axes: which way is up and which is north (unit, orthogonal); east is
/// north x up. Defaults: Y up, -Z north (so +X is east).
struct SceneAxes {
  Vec3 up{0, 1, 0}, north{0, 0, -1};
  /// "+Y", "-z", or "X,Y,Z"; InputError naming `what` otherwise.
  static Vec3 parseAxis(const std::string& text, const std::string& what);
  /// InputError unless up and north are unit and orthogonal.
  void check() const;
};

struct SunPosition {
  /// Topocentric, refraction included when asked for: zenith distance, azimuth from north
  /// through east, elevation above the horizon (degrees).
  double zenithDeg = 0, azimuthDeg = 0, elevationDeg = 0;
  /// Apparent geocentric place on the true equator and equinox of date (degrees).
  double rightAscensionDeg = 0, declinationDeg = 0;
  /// The sun's centre is below the horizon: no sunlight to bake.
  bool night = false;
  /// The direction of the sunlight, from the sun into the scene, in the scene's axes.
  Vec3 direction;
};

/// The sun at `t` from `place`. UT1 = UTC (within 0.9 s); TT from UTC through ERFA's
/// leap-second table, or TT = UT1 + deltaT when deltaT (seconds, TT - UT1) is given, as
/// the SPA paper takes it. InputError for a place,
/// atmosphere or instant out of range (latitude beyond +-90, longitude beyond +-180,
/// height beyond -12 km..100 km, pressure beyond 0..2000 mbar, temperature beyond -90..60 C,
/// years outside 1800..2500).
SunPosition sunPosition(const UtcInstant& t, const Place& place, const Atmosphere& air = {},
                        std::optional<double> deltaTSeconds = std::nullopt, const SceneAxes& axes = {});

}  // namespace cpvs
