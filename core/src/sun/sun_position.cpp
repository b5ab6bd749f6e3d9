#include "cpvs/sun/sun_position.h"

#include <erfa.h>
#include <erfam.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <regex>

#include "cpvs/base/error.h"
#include "cpvs/base/parse.h"

namespace cpvs {

namespace {

constexpr double kDeg = std::numbers::pi / 180;

[[noreturn]] void badTime(const std::string& what, const std::string& text, const std::string& why) {
  throw InputError(what + " '" + text + "': " + why +
                   " (expected ISO 8601 with a zone, e.g. 2003-10-17T12:30:30-07:00 or 2024-06-21T12:00:00Z)");
}

// Two-part Julian dates of one instant in the time scales the sun needs.
struct TimeScales {
  double tt1, tt2, ut11, ut12;
};

TimeScales timeScales(const UtcInstant& t, std::optional<double> deltaT) {
  double utc1 = 0, utc2 = 0, tai1 = 0, tai2 = 0, tt1 = 0, tt2 = 0, ut11 = 0, ut12 = 0;
  const int s = eraDtf2d("UTC", t.year, t.month, t.day, t.hour, t.minute, t.second, &utc1, &utc2);
  if (s < 0) throw InputError("the instant " + formatUtcInstant(t) + " is not a valid UTC date and time");
  // UT1 = UTC (they differ by under 0.9 s); TT from the leap-second table, or, as the
  // SPA paper does, UT1 + delta T when delta T is given.
  if (eraUtcut1(utc1, utc2, 0.0, &ut11, &ut12) < 0)
    throw InputError("the instant " + formatUtcInstant(t) + " cannot be converted to UT1");
  if (deltaT) {
    eraUt1tt(ut11, ut12, *deltaT, &tt1, &tt2);
  } else if (eraUtctai(utc1, utc2, &tai1, &tai2) < 0 || eraTaitt(tai1, tai2, &tt1, &tt2) != 0) {
    throw InputError("the instant " + formatUtcInstant(t) + " cannot be converted to TT");
  }
  return {tt1, tt2, ut11, ut12};
}

void inRange(double v, double lo, double hi, const std::string& what) {
  if (!(v >= lo && v <= hi))
    throw InputError(what + " " + std::to_string(v) + " is outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
}

}  // namespace

UtcInstant parseUtcInstant(const std::string& text, const std::string& what) {
  static const std::regex form(
      R"(^(\d{4})-(\d{2})-(\d{2})[T ](\d{2}):(\d{2})(?::(\d{2}(?:\.\d+)?))?(Z|z|([+-])(\d{2}):?(\d{2}))$)");
  std::smatch m;
  if (!std::regex_match(text, m, form)) badTime(what, text, m.empty() ? "not a date and time with a zone" : "");
  UtcInstant t;
  t.year = std::stoi(m[1]);
  t.month = std::stoi(m[2]);
  t.day = std::stoi(m[3]);
  t.hour = std::stoi(m[4]);
  t.minute = std::stoi(m[5]);
  t.second = m[6].matched ? std::stod(m[6]) : 0.0;
  if (t.month < 1 || t.month > 12 || t.day < 1 || t.day > 31 || t.hour > 23 || t.minute > 59 || t.second >= 61)
    badTime(what, text, "a field is out of range");
  if (m[8].matched) {
    const int sign = m[8] == "-" ? -1 : 1, zh = std::stoi(m[9]), zm = std::stoi(m[10]);
    if (zh > 14 || zm > 59) badTime(what, text, "the zone is out of range");
    // Local = UTC + offset: move to UTC through a Julian date, which keeps days and months right.
    double d1 = 0, d2 = 0;
    if (eraCal2jd(t.year, t.month, t.day, &d1, &d2) != 0) badTime(what, text, "not a calendar date");
    const double minutes = t.hour * 60.0 + t.minute - sign * (zh * 60.0 + zm);
    const double whole = std::floor(minutes / 1440.0);
    int iy, im, id;
    double fd;
    if (eraJd2cal(d1, d2 + whole, &iy, &im, &id, &fd) != 0) badTime(what, text, "not a calendar date");
    const double rest = minutes - whole * 1440.0;
    t.year = iy, t.month = im, t.day = id;
    t.hour = int(rest / 60), t.minute = int(rest - t.hour * 60);
  }
  double j1, j2;
  if (eraDtf2d("UTC", t.year, t.month, t.day, t.hour, t.minute, t.second, &j1, &j2) < 0)
    badTime(what, text, "not a valid UTC date and time");
  return t;
}

std::string formatUtcInstant(const UtcInstant& t) {
  char buf[64];
  if (t.second == std::floor(t.second))
    std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02dZ", t.year, t.month, t.day, t.hour, t.minute, int(t.second));
  else
    std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%06.3fZ", t.year, t.month, t.day, t.hour, t.minute, t.second);
  return buf;
}

namespace {

// Days from 1970-01-01 of a proleptic Gregorian date (H. Hinnant's algorithm).
int64_t daysFromCivil(int64_t y, unsigned m, unsigned d) {
  y -= m <= 2;
  const int64_t era = (y >= 0 ? y : y - 399) / 400;
  const unsigned yoe = unsigned(y - era * 400);
  const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + int64_t(doe) - 719468;
}

}  // namespace

int64_t unixMillis(const UtcInstant& t) {
  const int64_t days = daysFromCivil(t.year, unsigned(t.month), unsigned(t.day));
  const double seconds = std::min(t.second, 59.999);  // a leap second is the minute's last millisecond
  return ((days * 24 + t.hour) * 60 + t.minute) * 60000 + int64_t(std::llround(seconds * 1000));
}

UtcInstant utcFromUnixMillis(int64_t ms) {
  int64_t days = ms >= 0 ? ms / 86400000 : -((-ms + 86399999) / 86400000);
  int64_t rest = ms - days * 86400000;
  days += 719468;
  const int64_t era = (days >= 0 ? days : days - 146096) / 146097;
  const unsigned doe = unsigned(days - era * 146097);
  const unsigned yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const unsigned doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const unsigned mp = (5 * doy + 2) / 153;
  UtcInstant t;
  t.day = int(doy - (153 * mp + 2) / 5 + 1);
  t.month = int(mp < 10 ? mp + 3 : mp - 9);
  t.year = int(int64_t(yoe) + era * 400 + (t.month <= 2));
  t.hour = int(rest / 3600000);
  rest -= int64_t(t.hour) * 3600000;
  t.minute = int(rest / 60000);
  t.second = double(rest - int64_t(t.minute) * 60000) / 1000.0;
  return t;
}

Vec3 SceneAxes::parseAxis(const std::string& text, const std::string& what) {
  if (text.size() == 2 && (text[0] == '+' || text[0] == '-')) {
    const double s = text[0] == '-' ? -1 : 1;
    switch (text[1]) {
      case 'x': case 'X': return {s, 0, 0};
      case 'y': case 'Y': return {0, s, 0};
      case 'z': case 'Z': return {0, 0, s};
      default: break;
    }
  }
  const Vec3 v = parseVec3(text, what);
  const double n = length(v);
  if (!(n > 0) || !std::isfinite(n)) throw InputError(what + " '" + text + "' is not a direction");
  return v / n;
}

void SceneAxes::check() const {
  if (std::abs(length(up) - 1) > 1e-9 || std::abs(length(north) - 1) > 1e-9) throw InputError("--up and --north must be unit vectors");
  if (std::abs(dot(up, north)) > 1e-9) throw InputError("--up and --north must be at right angles");
}

SunPosition sunPosition(const UtcInstant& t, const Place& place, const Atmosphere& air, std::optional<double> deltaT,
                        const SceneAxes& axes) {
  inRange(place.latitudeDeg, -90, 90, "latitude");
  inRange(place.longitudeDeg, -180, 180, "longitude");
  inRange(place.heightM, -12000, 100000, "height (m)");
  inRange(air.pressureMbar, 0, 2000, "pressure (mbar)");
  inRange(air.temperatureC, -90, 60, "temperature (C)");
  inRange(t.year, 1800, 2500, "year");
  if (deltaT) inRange(*deltaT, -1e5, 1e5, "delta T (s)");
  axes.check();
  const TimeScales ts = timeScales(t, deltaT);

  // The sun's geometric direction from the geocentre (the Earth's heliocentric position,
  // reversed; the sun's own motion during the light time is below 0.01"), then annual
  // aberration with the Earth's barycentric velocity.
  double pvh[2][3], pvb[2][3];
  eraEpv00(ts.tt1, ts.tt2, pvh, pvb);
  double toSun[3] = {-pvh[0][0], -pvh[0][1], -pvh[0][2]};
  const double distanceAu = eraPm(toSun);
  double natural[3], v[3], apparent[3];
  eraSxp(1.0 / distanceAu, toSun, natural);
  eraSxp(ERFA_AULT / ERFA_DAYSEC, pvb[1], v);
  eraAb(natural, v, distanceAu, std::sqrt(1 - eraPm(v) * eraPm(v)), apparent);
  // To the true equator and equinox of date (IAU 2006/2000A), then to the rotating Earth
  // by Greenwich apparent sidereal time (polar motion, under 1", left out).
  double npb[3][3], ofDate[3];
  eraPnm06a(ts.tt1, ts.tt2, npb);
  eraRxp(npb, apparent, ofDate);
  SunPosition out;
  double ra = 0, dec = 0;
  eraC2s(ofDate, &ra, &dec);
  out.rightAscensionDeg = eraAnp(ra) / kDeg;
  out.declinationDeg = dec / kDeg;
  double earth[3][3], terrestrial[3];
  eraIr(earth);
  eraRz(eraGst06a(ts.ut11, ts.ut12, ts.tt1, ts.tt2), earth);
  eraRxp(earth, ofDate, terrestrial);
  // Topocentric: from the observer on the WGS84 ellipsoid (parallax up to 8.8").
  const double lon = place.longitudeDeg * kDeg, lat = place.latitudeDeg * kDeg;
  double observer[3];
  if (eraGd2gc(ERFA_WGS84, lon, lat, place.heightM, observer) != 0) throw InputError("the place cannot be mapped to the ellipsoid");
  double topo[3];
  for (int i = 0; i < 3; ++i) topo[i] = terrestrial[i] * distanceAu * ERFA_DAU - observer[i];
  double unit[3];
  eraSxp(1.0 / eraPm(topo), topo, unit);
  const Vec3 s{unit[0], unit[1], unit[2]};
  const Vec3 east{-std::sin(lon), std::cos(lon), 0};
  const Vec3 north{-std::sin(lat) * std::cos(lon), -std::sin(lat) * std::sin(lon), std::cos(lat)};
  const Vec3 up{std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon), std::sin(lat)};
  double elevation = std::asin(std::clamp(dot(s, up), -1.0, 1.0)) / kDeg;
  double azimuth = std::atan2(dot(s, east), dot(s, north)) / kDeg;
  if (azimuth < 0) azimuth += 360;
  // Refraction as the SPA paper applies it (Bennett's formula scaled by pressure and
  // temperature), above the depth where the sun's upper limb still shows.
  if (air.pressureMbar > 0 && elevation >= -(0.26667 + 0.5667)) {
    const double e0 = elevation;
    elevation += air.pressureMbar / 1010.0 * 283.0 / (273.0 + air.temperatureC) * 1.02 /
                 (60.0 * std::tan((e0 + 10.3 / (e0 + 5.11)) * kDeg));
  }
  out.elevationDeg = elevation;
  out.zenithDeg = 90 - elevation;
  out.azimuthDeg = azimuth;
  out.night = elevation < 0;
  // Into the scene: east is north x up there too.
  const Vec3 sceneEast = cross(axes.north, axes.up);
  const double ce = std::cos(elevation * kDeg), se = std::sin(elevation * kDeg);
  const Vec3 toward = sceneEast * (ce * std::sin(azimuth * kDeg)) + axes.north * (ce * std::cos(azimuth * kDeg)) + axes.up * se;
  out.direction = -toward;
  return out;
}

}  // namespace cpvs
