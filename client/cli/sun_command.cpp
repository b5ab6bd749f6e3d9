// `cpvs sun`: where the sun stands for a place and an instant, and the direction of its
// light in the scene's axes, for `cpvs bake --sun-dir`.
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include "cli_util.h"
#include "commands.h"
#include "cpvs/base/error.h"
#include "cpvs/sun/sun_position.h"

namespace cpvs::cli {

namespace {

struct SunArgs {
  double latitude = 0, longitude = 0, height = 0, pressure = 0, temperature = 10, deltaT = 0;
  std::string time, up = "+Y", north = "-Z";
  bool json = false;
};

int runSun(const SunArgs& a, bool haveDeltaT, bool haveTemperature) {
  if (haveTemperature && a.pressure == 0)
    throw InputError("--temperature only matters with --pressure (refraction); give both or neither");
  const UtcInstant t = parseUtcInstant(a.time);
  SceneAxes axes;
  axes.up = SceneAxes::parseAxis(a.up, "--up");
  axes.north = SceneAxes::parseAxis(a.north, "--north");
  const SunPosition s = sunPosition(t, {a.latitude, a.longitude, a.height}, {a.pressure, a.temperature},
                                    haveDeltaT ? std::optional<double>(a.deltaT) : std::nullopt, axes);
  if (a.json) {
    std::printf("{\n  \"time_utc\": %s,\n  \"night\": %s,\n  \"zenith_deg\": %s,\n  \"azimuth_deg\": %s,\n"
                "  \"elevation_deg\": %s,\n  \"right_ascension_deg\": %s,\n  \"declination_deg\": %s,\n"
                "  \"refraction\": %s,\n  \"direction\": %s\n}\n",
                jsonString(formatUtcInstant(t)).c_str(), s.night ? "true" : "false", jsonNumber(s.zenithDeg).c_str(),
                jsonNumber(s.azimuthDeg).c_str(), jsonNumber(s.elevationDeg).c_str(),
                jsonNumber(s.rightAscensionDeg).c_str(), jsonNumber(s.declinationDeg).c_str(),
                a.pressure > 0 ? "true" : "false",
                s.night ? "null"
                        : ("[" + jsonNumber(s.direction.x) + ", " + jsonNumber(s.direction.y) + ", " +
                           jsonNumber(s.direction.z) + "]").c_str());
    return 0;
  }
  std::printf("Sun at %s from %.6f, %.6f (%.1f m)%s\n", formatUtcInstant(t).c_str(), a.latitude, a.longitude, a.height,
              a.pressure > 0 ? ", refraction included" : "");
  std::printf("  zenith %.5f deg, azimuth %.5f deg (from north, eastward), elevation %.5f deg\n", s.zenithDeg,
              s.azimuthDeg, s.elevationDeg);
  if (s.night) {
    std::printf("  night: the sun is %.3f deg below the horizon; there is no sunlight to bake\n", -s.elevationDeg);
    return 0;
  }
  std::printf("  light direction in the scene (up %s, north %s): %.9f,%.9f,%.9f\n", a.up.c_str(), a.north.c_str(),
              s.direction.x, s.direction.y, s.direction.z);
  std::printf("  bake it: cpvs bake SCENE --sun-dir %.9f,%.9f,%.9f ...\n", s.direction.x, s.direction.y, s.direction.z);
  return 0;
}

}  // namespace

void addSunCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<SunArgs>();
  CLI::App* c = app.add_subcommand(
      "sun", "Where the sun stands for a place and a UTC instant (ERFA, IAU 2006/2000A), and its light's direction");
  c->add_option("--lat", a->latitude, "Geodetic latitude, degrees north (-90..90)")->required();
  c->add_option("--lon", a->longitude, "Longitude, degrees east (-180..180)")->required();
  c->add_option("--time", a->time, "The instant, ISO 8601 with a zone: 2003-10-17T12:30:30-07:00, 2024-06-21T12:00Z")
      ->required();
  c->add_option("--height", a->height, "Height above the WGS84 ellipsoid, metres")->capture_default_str();
  auto* pressure = c->add_option("--pressure", a->pressure, "Air pressure in mbar: refraction (none without it)");
  auto* temperature = c->add_option("--temperature", a->temperature, "Air temperature in C, with --pressure");
  auto* deltaT = c->add_option("--delta-t", a->deltaT,
                               "TT - UT1 in seconds, as the SPA paper takes it (default: from the leap-second table, UT1 = UTC)");
  c->add_option("--up", a->up, "The scene's up axis: +X, -Y, ... or X,Y,Z")->capture_default_str();
  c->add_option("--north", a->north, "The scene's north axis (east is north x up)")->capture_default_str();
  c->add_flag("--json", a->json,
              "Print JSON: time_utc, night, zenith_deg, azimuth_deg, elevation_deg, right_ascension_deg, "
              "declination_deg, refraction, direction (unit, from the sun into the scene; null at night)");
  (void)pressure;
  c->callback([a, &status, deltaT, temperature] { status = runSun(*a, deltaT->count() > 0, temperature->count() > 0); });
}

}  // namespace cpvs::cli
