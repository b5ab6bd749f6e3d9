// `cpvs accuracy`: bakes a scene at several resolutions and measures each bake, and plain
// shadow maps, against exact ray-traced visibility on the same surface points.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <memory>

#include "bake_flags.h"
#include "cli_util.h"
#include "commands.h"
#include "cpvs/base/error.h"
#include "cpvs/base/parse.h"
#include "cpvs/eval/accuracy.h"
#include "cpvs/eval/accuracy_report.h"

namespace cpvs::cli {

namespace {

struct AccuracyArgs {
  std::string scene, out, resolutions = "1K,2K,4K";
  SunFlags sun;
  uint64_t samples = 100000, pcfSamples = 10000, seed = 1, maxFullMapMb = 2048;
  double timingSeconds = 0.2;
  int tileSize = 4096, threads = 0;
  std::vector<std::string> cameras;
  OptionFlags receivers;  // --receivers, --receiver-box, --receiver-pcf
  bool quiet = false;
};

/// Progress lines on stderr: one when a stage starts and ends, and at most every 10 % or
/// 5 s in between (stdout carries only the table).
class StageLog {
 public:
  explicit StageLog(bool enabled) : enabled_(enabled), start_(std::chrono::steady_clock::now()) {}
  bool operator()(const Progress& p) {
    const std::string& stage = p.stage;
    const uint64_t done = p.done, total = p.total;
    if (!enabled_ || total == 0) return true;
    const double t = secondsSince(start_);
    const int percent = int(100.0 * double(done) / double(total));
    if (stage != stage_ || done == total || percent / 10 != percent_ / 10 || t - last_ >= 5) {
      std::fprintf(stderr, "[%7.1fs] %-14s %3d%%  %llu/%llu\n", t, stage.c_str(), percent,
                   static_cast<unsigned long long>(done), static_cast<unsigned long long>(total));
      std::fflush(stderr);
      stage_ = stage;
      percent_ = percent;
      last_ = t;
    }
    return true;
  }

 private:
  bool enabled_;
  std::chrono::steady_clock::time_point start_;
  std::string stage_;
  int percent_ = -1;
  double last_ = 0;
};

std::vector<int> parseResolutions(const std::string& text) {
  std::vector<int> out;
  for (const std::string& item : splitList(text)) {
    try {
      out.push_back(parseResolution(item));
    } catch (const InputError& e) {
      throw InputError("--resolutions '" + text + "': " + e.what());
    }
  }
  if (out.empty()) throw InputError("--resolutions '" + text + "': no resolution");
  return out;
}

// Creates the output folder and checks that a file can be written there, before hours of
// measuring.
void prepareOutDir(const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir))
    throw InputError("--out " + dir + ": cannot create the folder" + (ec ? ": " + ec.message() : " (a file is in the way)"));
  const fs::path probe = fs::path(dir) / (".cpvs-accuracy-probe." + std::to_string(::getpid()));
  std::FILE* f = std::fopen(probe.c_str(), "w");
  if (!f) throw InputError("--out " + dir + ": the folder is not writable");
  std::fclose(f);
  fs::remove(probe, ec);
}

int runAccuracy(const AccuracyArgs& a) {
  const auto limit = threadLimit(a.threads);
  AccuracyOptions opt;
  opt.log2Resolutions = parseResolutions(a.resolutions);
  if (a.samples < 100) throw InputError("--samples " + std::to_string(a.samples) + " must be at least 100");
  if (a.pcfSamples < 1) throw InputError("--pcf-samples must be at least 1");
  opt.samples = a.samples;
  opt.pcfSamples = std::min(a.pcfSamples, a.samples);
  opt.seed = a.seed;
  opt.maxFullShadowMapBytes = a.maxFullMapMb << 20;
  if (!(a.timingSeconds >= 0) || a.timingSeconds > 3600)
    throw InputError("--timing-seconds " + std::to_string(a.timingSeconds) + " must be between 0 and 3600");
  opt.minTimingSeconds = a.timingSeconds;
  opt.bake.log2TileSize = log2TileSizeOf(uint64_t(std::max(a.tileSize, 0)), "--tile-size");
  opt.receivers = receiversOf(a.receivers);
  const LightFrame frame = lightFromFlags(a.sun.dir, a.sun.elevation, a.sun.azimuth);
  prepareOutDir(a.out);

  const Scene scene = openScene(a.scene);
  for (const std::string& c : a.cameras)
    opt.cameras.push_back(c == "default" ? defaultCamera(scene, frame.dir, opt.cameraAspect) : Camera::parse(c));
  if (!a.quiet)
    std::fprintf(stderr, "%s: %zu triangles, light (%.4f, %.4f, %.4f), resolutions %s, %llu samples (PCF on %llu)\n",
                 scene.name.c_str(), scene.triangleCount(), frame.dir.x, frame.dir.y, frame.dir.z,
                 a.resolutions.c_str(), static_cast<unsigned long long>(opt.samples),
                 static_cast<unsigned long long>(opt.pcfSamples));
  StageLog log(!a.quiet);
  const AccuracyReport report =
      measureAccuracy(scene, frame, opt, [&](const Progress& p) { return log(p); });
  writeAccuracyReport(report, a.out);
  std::cout << accuracyTable(report);
  if (!a.quiet)
    std::fprintf(stderr, "Wrote %s/accuracy.md, accuracy.csv, accuracy.svg (%.1f s)\n", a.out.c_str(), report.seconds);
  return 0;
}

}  // namespace

void addAccuracyCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<AccuracyArgs>();
  CLI::App* c = app.add_subcommand(
      "accuracy",
      "Bake a scene at several resolutions and measure each bake, and plain 16-bit shadow maps of the same bytes and "
      "of full resolution, against exact shadow rays on the same surface points: mismatch by distance to the shadow "
      "boundary, PCF error, bake time, bytes, lookup time. Writes accuracy.md, accuracy.csv and accuracy.svg");
  c->add_option("scene", a->scene, "Scene file (glTF/GLB, OBJ, DAE, PLY, FBX, STL, ...), city[:BLOCKS[:SEED]] or landscape[:SIZE[:SEED]]")
      ->required();
  c->add_option("--out,-o", a->out, "Output folder (created)")->required();
  addSunFlags(c, a->sun);
  c->add_option("--resolutions", a->resolutions, "Comma-separated grid resolutions, e.g. 1K,2K,4K,8K,16K")
      ->capture_default_str();
  c->add_option("--samples,-n", a->samples, "Surface points (at least 100), the same for every resolution")
      ->capture_default_str();
  c->add_option("--camera", a->cameras,
                "Sample what this camera sees (EX,EY,EZ,TX,TY,TZ[,FOV], 16:9; 'default' = the render's view) "
                "instead of every surface uniformly by area; repeat for several cameras")
      ->take_all()
      ->allow_extra_args(false);
  addReceiverFlags(c, a->receivers);
  c->add_option("--pcf-samples", a->pcfSamples, "How many of them get PCF references (shadow rays per footprint texel)")
      ->capture_default_str();
  c->add_option("--seed", a->seed, "Sampling seed")->capture_default_str();
  c->add_option("--tile-size", a->tileSize, "Bake tile size in texels (power of two >= 8)")->capture_default_str();
  c->add_option("--max-full-map-mb", a->maxFullMapMb, "Largest full-resolution shadow map rendered (MiB)")
      ->capture_default_str();
  c->add_option("--timing-seconds", a->timingSeconds, "Each lookup timing repeats its batch at least this long")
      ->capture_default_str();
  addThreadsFlag(c, a->threads);
  c->add_flag("--quiet,-q", a->quiet, "No progress output");
  c->callback([a, &status] { status = runAccuracy(*a); });
}

}  // namespace cpvs::cli
