#include "cpvs/base/error.h"
#include "cli_util.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace cpvs::cli {

LightFrame lightFromFlags(const std::string& sunDir, double elevation, double azimuth) {
  if (!sunDir.empty()) {
    if (!std::isnan(elevation) || !std::isnan(azimuth))
      throw InputError("give either --sun-dir or --sun-elevation/--sun-azimuth, not both");
    return LightFrame::fromDirection(parseVec3(sunDir, "--sun-dir"));
  }
  if (std::isnan(elevation)) throw InputError("give the light: --sun-dir X,Y,Z or --sun-elevation DEG");
  return LightFrame::fromElevationAzimuth(elevation, std::isnan(azimuth) ? 0.0 : azimuth);
}

std::string formatSeconds(double s) {
  char buf[32];
  if (s < 60)
    std::snprintf(buf, sizeof buf, "%.1fs", s);
  else if (s < 3600)
    std::snprintf(buf, sizeof buf, "%dm%02ds", int(s) / 60, int(s) % 60);
  else
    std::snprintf(buf, sizeof buf, "%dh%02dm", int(s) / 3600, int(s) / 60 % 60);
  return buf;
}

std::string humanBytes(uint64_t b) {
  const char* units[] = {"B", "KB", "MB", "GB", "TB"};
  double v = double(b);
  int u = 0;
  while (v >= 1000 && u < 4) {
    v /= 1000;
    ++u;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.2f %s", v, units[u]);
  return buf;
}

namespace {
double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
// What a stage counts: a light bundle's bake counts grids, every other stage tiles.
const char* unitOf(const std::string& stage) { return stage == "lights" ? "grids" : "tiles"; }

}  // namespace

ProgressDisplay::ProgressDisplay(bool enabled) : enabled_(enabled), tty_(::isatty(STDERR_FILENO)), start_(now()) {}

ProgressDisplay::~ProgressDisplay() { finish(); }

bool ProgressDisplay::update(const Progress& p) {
  const std::string& stage = p.stage;
  const uint64_t done = p.done, total = p.total;
  if (!enabled_ || total == 0) return true;
  double t = now() - start_;
  double frac = double(done) / double(total);
  double eta = p.secondsLeft >= 0 ? p.secondsLeft : done > 0 ? t / frac - t : 0;
  int percent = int(frac * 100);
  if (tty_) {
    const int width = 30;
    int filled = int(frac * width);
    std::fprintf(stderr, "\r%-8s [%s%s] %3d%%  %llu/%llu %s  %.1fs elapsed  ETA %.1fs ", stage.c_str(),
                 std::string(filled, '#').c_str(), std::string(width - filled, ' ').c_str(), percent,
                 static_cast<unsigned long long>(done), static_cast<unsigned long long>(total), unitOf(stage), t,
                 done > 0 || p.secondsLeft >= 0 ? eta : 0.0);
    std::fflush(stderr);
    drawn_ = true;
  } else if (done == total || percent / 10 != lastPercent_ / 10 || t - lastLog_ >= 5) {
    spdlog::info("{}: {}/{} {} ({}%), {:.1f}s elapsed, ETA {:.1f}s", stage, done, total, unitOf(stage), percent, t, eta);
    lastLog_ = t;
    lastPercent_ = percent;
  }
  return true;
}

void ProgressDisplay::finish() {
  if (drawn_) std::fprintf(stderr, "\n");
  drawn_ = false;
}

}  // namespace cpvs::cli

namespace cpvs::cli {

Scene openMatchingScene(const std::string& spec, const CpvsArtifact& artifact) {
  return openMatchingScene(spec, artifact.sceneHash);
}

Scene openMatchingScene(const std::string& spec, const Hash128& baked) {
  Scene scene = openScene(spec);
  Hash128 h = sceneHash(scene);
  if (!(h == baked))
    throw InputError("scene '" + spec + "' (hash " + h.hex() + ") is not the scene this file was baked from (hash " +
                     baked.hex() + ")");
  return scene;
}

void checkGridInTheAir(const CpvsArtifact& artifact, const std::string& file, const std::string& flag) {
  const ReceiverKind kind = artifact.options.receivers;
  if (kind == ReceiverKind::Everywhere) return;
  if (kind == ReceiverKind::Volume || kind == ReceiverKind::Cameras) {
    std::fprintf(stderr, "note: %s was baked for '%s' receivers: %s is answered right only inside the declared volume\n",
                 file.c_str(), optionName(kind), flag.c_str());
    return;
  }
  throw InputError(flag + ": " + file + " was baked for '" + optionName(kind) +
                   "' receivers, whose grid is undefined in the air; light along a segment needs a bake with "
                   "--receivers everywhere (or a volume holding the segments)");
}

}  // namespace cpvs::cli
