// The flags that describe a bake, shared by `bake`, `submit` and `accuracy`: the light,
// and the bake options with the names of bake/options.h.
#pragma once

#include "cpvs/bake/bake_plan.h"

#include <CLI/CLI.hpp>

#include <tbb/global_control.h>

#include <cmath>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/bake/receivers.h"
#include "cpvs/base/vec3.h"
#include "cpvs/light/frame.h"
#include "cpvs/light/area_light.h"
#include "cpvs/light/light.h"
#include "cpvs/scene/scene.h"

namespace cpvs::cli {

/// --threads,-j: how many threads every parallel step may use (0: all cores).
void addThreadsFlag(CLI::App* c, int& threads);
/// Holds TBB, and with it everything parallel in a bake (rendering, the camera cast,
/// Embree's builds), to `threads` while it lives; nothing for 0.
std::unique_ptr<tbb::global_control> threadLimit(int threads);

/// --sun-dir, or --sun-elevation with --sun-azimuth.
struct SunFlags {
  std::string dir;
  double elevation = NAN, azimuth = NAN;
};
void addSunFlags(CLI::App* c, SunFlags& sun);

/// --spot, --point, --lights, --scene-lights, --footprint: local lights, baked into a
/// light bundle (`bake`) or planned (`plan`).
struct LightFlags {
  std::vector<std::string> spots, points, areas;
  std::string lightsFile;
  bool sceneLights = false;
  double footprint = 0;
  bool given() const {
    return !spots.empty() || !points.empty() || !areas.empty() || !lightsFile.empty() || sceneLights;
  }
};
void addLightFlags(CLI::App* c, LightFlags& lights);
/// The lights of the lights file, --spot and --point, then the VPLs of each --area-light
/// (area lights 1, 2, ... in flag order, each seeded by its number), read before the scene
/// is opened; InputError naming the flag for a malformed one, or a bad --footprint.
std::vector<Light> flagLights(const LightFlags& flags);
/// The --area-light flags' area lights, "area k" seeded k (what flagLights expands into
/// VPLs, and what `submit` sends the farm to expand alike).
std::vector<AreaLight> flagAreaLights(const LightFlags& flags);
/// Those lights after the scene's own (--scene-lights; InputError naming `sceneSpec`
/// when it has none).
std::vector<Light> withSceneLights(const LightFlags& flags, std::vector<Light> given, const Scene& scene,
                                   const std::string& sceneSpec);
/// --footprint, or the scene's diagonal / 4096 (the texels of a 4K sun over it).
double footprintOf(const LightFlags& flags, const Scene& scene);
/// InputError when local lights are asked for with a sun flag.
void checkNoSunWithLights(const SunFlags& sun);

/// --closed, --exit, --cull, --compress, --undefined, --renderer, --tile-size, --depth-slices.
struct OptionFlags {
  std::string closed = optionName(ClosedMode::Auto), exit = optionName(ExitMode::Exact), cull = "on",
              compress = optionName(CompressMode::TopDown), undefinedRule = optionName(UndefinedRule::Aligned),
              renderer = optionName(BakeOptions{}.renderer);
  int tileSize = 1 << kDefaultLog2TileSize;
  uint64_t depthSlices = 0;  // 0: as many as the resolution
  std::string receivers = optionName(ReceiverKind::Everywhere);
  std::vector<std::string> media;  // --medium SIGMA_S,SIGMA_A[,G]: what the plan offers light through
  std::vector<std::string> receiverBoxes, cameraRegions;
  int receiverPcf = kMaxPcfWidthOption;
  double viewDistance = 0;
  std::string cameraVisibility;  // "" (the camera file's, else faced), faced, sampled
  double cameraSpacing = 0;
  int cameraRays = 0;
  std::string groundLayer;  // "[FROM:]TO"
  double groundSlope = kDefaultGroundSlopeDeg;
};
/// The media --medium declares, as the plan takes them ("medium 1", ...); InputError for a
/// bad one.
std::vector<BakePlan::Medium> declaredMedia(const OptionFlags& flags);

/// `tileHelp` says what the tile size means to this command.
void addOptionFlags(CLI::App* c, OptionFlags& options, const std::string& tileHelp);
/// --receivers, --receiver-box, --ground-layer, --ground-slope, --receiver-pcf,
/// --camera-region, --view-distance, --camera-visibility, --camera-spacing, --camera-rays
/// (part of addOptionFlags).
void addReceiverFlags(CLI::App* c, OptionFlags& options);
/// The bake options the flags name; InputError naming the flag otherwise.
BakeOptions optionsOf(const OptionFlags& flags);
/// Boxes given as MINX,MINY,MINZ,MAXX,MAXY,MAXZ (--receiver-box, --camera-region) as
/// (min, max); InputError naming `flag` unless six numbers with min < max.
std::vector<std::pair<Vec3, Vec3>> boxesOf(const std::vector<std::string>& texts, const std::string& flag);
/// --ground-layer "[FROM:]TO" as (from, to) scene units above the ground, (0, 0) when
/// empty; InputError unless 0 <= FROM < TO, finite.
std::pair<double, double> groundLayerOf(const std::string& text);
/// The receiver declaration of --receivers, --receiver-box, --receiver-pcf and the camera
/// flags, its volume loaded (a mesh file, boxes) and its camera file read (`cameras:FILE.json`,
/// which the camera flags add to or override); InputError naming the flag otherwise.
ReceiverDeclaration receiversOf(const OptionFlags& flags);
/// Whether any camera flag is given (--camera-region, --view-distance, --camera-visibility,
/// --camera-spacing, --camera-rays).
bool cameraFlagsGiven(const OptionFlags& flags);

/// The receiver declaration of an artifact, as `bake --json` and `inspect --json` show it:
/// {"kind": ..., "pcf": ..., "hash": ...} (pcf and hash null for everywhere).
std::string receiversJson(const BakeOptions& options, const Hash128& receiverHash);
/// One line for people: "surfaces, PCF up to 9 (hash ...)" or "everywhere".
std::string receiversText(const BakeOptions& options, const Hash128& receiverHash);

}  // namespace cpvs::cli
