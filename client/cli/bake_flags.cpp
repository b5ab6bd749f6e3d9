#include "bake_flags.h"

#include <algorithm>
#include <tuple>
#include <vector>

#include "cpvs/base/error.h"
#include "cpvs/bake/bake_lights.h"
#include "cpvs/base/parse.h"
#include "cpvs/light/area_light.h"
#include "cpvs/query/medium.h"
#include "cpvs/net/farm_model.h"
#include "cpvs/net/receiver_declaration.h"
#include "cpvs/scene/boxes.h"
#include "cpvs/query/normal_offset.h"
#include "cpvs/scene/import.h"

namespace cpvs::cli {

void addThreadsFlag(CLI::App* c, int& threads) {
  c->add_option("--threads,-j", threads, "Threads for every parallel step (0 = all cores)")
      ->capture_default_str()
      ->check(CLI::Range(0, 4096));
}

std::unique_ptr<tbb::global_control> threadLimit(int threads) {
  if (threads <= 0) return nullptr;
  return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(threads));
}

namespace {

template <class Option>
std::vector<std::string> namesOf() {
  const auto& names = OptionNames<Option>::kNames;
  return {names.begin(), names.end()};
}

}  // namespace

void addSunFlags(CLI::App* c, SunFlags& sun) {
  c->add_option("--sun-dir", sun.dir, "Light direction X,Y,Z, from the sun into the scene (any side)");
  c->add_option("--sun-elevation", sun.elevation, "Sun elevation above the horizon in degrees (0..90, Y up)");
  c->add_option("--sun-azimuth", sun.azimuth, "Sun azimuth in degrees (0 = towards +Z, 90 = towards +X)");
}

void addLightFlags(CLI::App* c, LightFlags& lights) {
  c->add_option("--spot", lights.spots,
                "A spot light X,Y,Z:DX,DY,DZ:CONE[:RANGE] (position, axis, half-angle in degrees, reach; no range: "
                "to the scene's far side); repeat for more. With local lights the file is a light bundle");
  c->add_option("--point", lights.points, "A point light X,Y,Z[:RANGE] (six 90-degree grids); repeat for more");
  c->add_option("--area-light", lights.areas,
                "An area light CX,CY,CZ:UX,UY,UZ:VX,VY,VZ[:K[:RES]]: a rectangle (centre, two edges; it shines "
                "towards U x V) sampled by K virtual point lights (default 64), each a cube of RESxRESxRES grids "
                "(default 128) whose soft visibility `query --soft` averages; repeat for more");
  c->add_option("--lights", lights.lightsFile,
                "A lights file: JSON {\"lights\": [{\"kind\": \"LIGHT_SPOT\", \"name\": ..., \"position\": "
                "{\"x\": ..}, \"direction\": .., \"coneDeg\": .., \"range\": .., \"colour\": .., \"intensity\": "
                "..}]} (LIGHT_POINT for a point light; near and resolution when not planned)")
      ->check(CLI::ExistingFile);
  c->add_flag("--scene-lights", lights.sceneLights,
              "The scene's own point and spot lights (glTF KHR_lights_punctual, COLLADA, FBX, ...; the "
              "procedural city's street lamps), before those of --lights, --spot and --point");
  c->add_option("--footprint", lights.footprint,
                "Local lights: the widest a texel may be at a light's far end, in scene units (picks each grid's "
                "resolution, up to 8K; default: the scene's diagonal / 4096)");
}

std::vector<BakePlan::Medium> declaredMedia(const OptionFlags& flags) {
  std::vector<BakePlan::Medium> out;
  for (size_t k = 0; k < flags.media.size(); ++k) {
    const Medium m = parseMedium(flags.media[k], "--medium");
    out.push_back({"medium " + std::to_string(k + 1), "declared", m.scattering, m.absorption, m.g, false, ""});
  }
  return out;
}

std::vector<Light> flagLights(const LightFlags& flags) {
  if (flags.footprint < 0 || !std::isfinite(flags.footprint)) throw InputError("--footprint must be positive");
  std::vector<Light> lights;
  if (!flags.lightsFile.empty()) lights = net::readLightsFile(flags.lightsFile);
  for (const std::string& s : flags.spots) lights.push_back(parseSpotFlag(s));
  for (const std::string& s : flags.points) lights.push_back(parsePointFlag(s));
  for (Light& l : vplsOf(flagAreaLights(flags))) lights.push_back(std::move(l));
  return lights;
}

std::vector<AreaLight> flagAreaLights(const LightFlags& flags) {
  std::vector<AreaLight> areas;
  for (size_t k = 0; k < flags.areas.size(); ++k) {
    AreaLight area = parseAreaLightFlag(flags.areas[k]);
    area.name = "area " + std::to_string(k + 1);
    area.seed = k + 1;
    // The rectangle is checked here (its VPLs' positions with the scene's bounds later).
    checkAreaLight(area, area.centre, area.centre, "--area-light " + std::to_string(k + 1));
    areas.push_back(std::move(area));
  }
  return areas;
}

std::vector<Light> withSceneLights(const LightFlags& flags, std::vector<Light> given, const Scene& scene,
                                   const std::string& sceneSpec) {
  if (!flags.sceneLights) return given;
  return withSceneLights(scene, std::move(given), "--scene-lights: " + sceneSpec);
}

double footprintOf(const LightFlags& flags, const Scene& scene) {
  return flags.footprint > 0 ? flags.footprint : defaultFootprint(scene);
}

void checkNoSunWithLights(const SunFlags& sun) {
  if (!sun.dir.empty() || !std::isnan(sun.elevation) || !std::isnan(sun.azimuth))
    throw InputError("--spot, --point, --lights and --scene-lights are local lights; the sun flags are for a sun bake");
}

void addOptionFlags(CLI::App* c, OptionFlags& o, const std::string& tileHelp) {
  c->add_option("--closed", o.closed, "Closed-geometry interiors: auto (watertight parts), on (all), off (none)")
      ->check(CLI::IsMember(namesOf<ClosedMode>()))->capture_default_str();
  c->add_option("--exit", o.exit, "Exit depth: exact (face counting) or approx (first back face)")
      ->check(CLI::IsMember(namesOf<ExitMode>()))->capture_default_str();
  c->add_option("--cull", o.cull, "Cull identical nodes during insertion (§3.2)")
      ->check(CLI::IsMember({"on", "off"}))->capture_default_str();
  c->add_option("--compress", o.compress, "Compression: topdown (§4.2), bottomup (§4.1), none (as inserted)")
      ->check(CLI::IsMember(namesOf<CompressMode>()))->capture_default_str();
  c->add_option("--undefined", o.undefinedRule,
                "Undefined voxels: aligned (the new rule, with every 8-slice slab of a column that its texels allow "
                "wholly lit or wholly shadowed: fewer nodes), new (§3.4: fewest masks per 8x8 column) or old (mixed "
                "-> shadowed)")
      ->check(CLI::IsMember(namesOf<UndefinedRule>()))->capture_default_str();
  c->add_option("--renderer", o.renderer,
                "Depth maps: raster (exact rasterization, fast) or embree (a ray per texel); they differ only on "
                "texels whose ray grazes an edge")
      ->check(CLI::IsMember(namesOf<Renderer>()))->capture_default_str();
  c->add_option("--tile-size", o.tileSize, tileHelp)->capture_default_str();
  c->add_option("--depth-slices", o.depthSlices,
                "Slices across the scene's depth along the sun, a power of two up to the resolution (default: the "
                "resolution, a cubic grid). Fewer are coarser in depth only, as a shadow map of that depth precision: "
                "4096 at 16K is the public peer's 16K x 16K x 4096 grid. Lookups then offset along the normal by "
                "slices, as many as on a cubic grid of that depth, reaching as many times further across");
  addReceiverFlags(c, o);
}

void addReceiverFlags(CLI::App* c, OptionFlags& o) {
  c->add_option("--receivers", o.receivers,
                "Who queries the shadows; every voxel their lookups never read is left free: everywhere (any point "
                "outside closed solids), surfaces (the front side of the scene's surfaces, with their geometric "
                "normals), surfaces-two-sided (both sides of open surfaces), volume[:MESH] (front sides plus any "
                "point, any normal, inside a closed mesh file and the --receiver-box boxes), cameras[:FILE] (the "
                "sides of surfaces that cameras see within --view-distance; FILE.json is a camera file: regions, "
                "points and paths, see docs/command-line.md; any other FILE a closed mesh of receiver volume)")
      ->capture_default_str();
  c->add_option("--receiver-box", o.receiverBoxes,
                "A box of the receiver volume, MINX,MINY,MINZ,MAXX,MAXY,MAXZ in scene units (repeatable; with "
                "--receivers volume)");
  c->add_option("--ground-layer", o.groundLayer,
                "With --receivers volume or cameras: receivers also anywhere from FROM (default 0) up to TO scene "
                "units above a walkable surface, with any normal: characters and vehicles on the ground "
                "([FROM:]TO; a layer that touches the ground costs as much as receivers everywhere there)");
  c->add_option("--ground-slope", o.groundSlope,
                "With --ground-layer: the steepest surface that is walkable, degrees from level (Y up)")
      ->capture_default_str();
  c->add_option("--medium", o.media,
                "SIGMA_S,SIGMA_A[,G]: a participating medium (fog) the bake is for, per world unit: the plan says "
                "whether its voxels answer light through it (query --segment, render --fog); nothing more is baked. "
                "Repeat for more");
  c->add_option("--receiver-pcf", o.receiverPcf, "The widest PCF filter receivers' lookups use (1, 3, 5, 7, 9)")
      ->capture_default_str();
  c->add_option("--camera-region", o.cameraRegions,
                "With --receivers cameras: a box cameras can be in, MINX,MINY,MINZ,MAXX,MAXY,MAXZ (repeatable)");
  c->add_option("--view-distance", o.viewDistance,
                "With --receivers cameras: how far cameras see (scene units); surfaces farther from every region "
                "do not receive");
  c->add_option("--camera-visibility", o.cameraVisibility,
                "With --receivers cameras: faced (every side a camera place faces, occluders ignored: conservative, "
                "the default) or sampled (the sides that rays from camera positions hit: smaller, may miss what is "
                "seen only between samples; verify measures how often)")
      ->check(CLI::IsMember(namesOf<CameraVisibility>()));
  c->add_option("--camera-spacing", o.cameraSpacing,
                "With --camera-visibility sampled: camera positions at most this far apart in regions and along "
                "paths, scene units (default: a sixteenth of the view distance)");
  c->add_option("--camera-rays", o.cameraRays,
                "With --camera-visibility sampled: rays per side of each of the six cube faces a position casts "
                "(default 128, at most 2048)");
}

std::vector<std::pair<Vec3, Vec3>> boxesOf(const std::vector<std::string>& texts, const std::string& flag) {
  std::vector<std::pair<Vec3, Vec3>> boxes;
  for (const std::string& text : texts) {
    const std::vector<double> v = parseNumbers(text, flag);
    if (v.size() != 6 || !(v[0] < v[3] && v[1] < v[4] && v[2] < v[5]))
      throw InputError(flag + ": '" + text + "' is not MINX,MINY,MINZ,MAXX,MAXY,MAXZ with min < max");
    boxes.push_back({{v[0], v[1], v[2]}, {v[3], v[4], v[5]}});
  }
  return boxes;
}

std::pair<double, double> groundLayerOf(const std::string& text) {
  if (text.empty()) return {0, 0};
  const InputError bad("--ground-layer: '" + text + "' is not [FROM:]TO with 0 <= FROM < TO");
  const size_t colon = text.find(':');
  auto one = [&](const std::string& part) {
    const std::vector<double> v = part.empty() ? std::vector<double>{} : parseNumbers(part, "--ground-layer");
    if (v.size() != 1) throw bad;
    return v[0];
  };
  const double from = colon == std::string::npos ? 0 : one(text.substr(0, colon));
  const double to = one(colon == std::string::npos ? text : text.substr(colon + 1));
  if (!(from >= 0 && from < to)) throw bad;
  return {from, to};
}

ReceiverDeclaration receiversOf(const OptionFlags& f) {
  ReceiverDeclaration d;
  const size_t colon = f.receivers.find(':');
  d.kind = parseOption<ReceiverKind>(f.receivers.substr(0, colon), "--receivers");
  d.maxPcf = f.receiverPcf;
  const bool cameras = d.kind == ReceiverKind::Cameras, volume = d.kind == ReceiverKind::Volume || cameras;
  if (colon != std::string::npos && !volume)
    throw InputError("--receivers: only 'volume' and 'cameras' take a file ('" + f.receivers + "')");
  if (!f.receiverBoxes.empty() && !volume) throw InputError("--receiver-box needs --receivers volume or cameras");
  if (!f.groundLayer.empty() && !volume) throw InputError("--ground-layer needs --receivers volume or cameras");
  if (f.groundSlope != kDefaultGroundSlopeDeg && f.groundLayer.empty())
    throw InputError("--ground-slope needs --ground-layer");
  if (!cameras && cameraFlagsGiven(f))
    throw InputError("--camera-region, --view-distance and --camera-visibility, -spacing, -rays need --receivers cameras");
  const std::string file = colon == std::string::npos ? "" : f.receivers.substr(colon + 1);
  const bool cameraFile = cameras && net::isCameraFile(file);
  if (volume) {
    if (!file.empty() && !cameraFile) d.volume = loadScene(file);
    for (const auto& [lo, hi] : boxesOf(f.receiverBoxes, "--receiver-box")) appendBox(d.volume, lo, hi);
    finalizeScene(d.volume);
    std::tie(d.groundLayerFrom, d.groundLayer) = groundLayerOf(f.groundLayer);
    d.groundSlopeDeg = f.groundSlope;
  }
  if (cameras) {
    if (cameraFile) net::setCameras(net::readCameraFile(file), d);
    for (const auto& box : boxesOf(f.cameraRegions, "--camera-region")) d.cameraRegions.push_back(box);
    if (f.viewDistance != 0) d.viewDistance = f.viewDistance;
    if (!f.cameraVisibility.empty()) d.cameraVisibility = parseOption<CameraVisibility>(f.cameraVisibility, "--camera-visibility");
    if (f.cameraSpacing != 0) d.cameraSpacing = f.cameraSpacing;
    if (f.cameraRays < 0) throw InputError("--camera-rays must be 0 (the default, 128) or more");
    if (f.cameraRays != 0) d.cameraRays = uint32_t(f.cameraRays);
  }
  try {
    checkReceiverDeclaration(d);
  } catch (const InputError& e) {
    throw InputError(std::string("--") + e.what());
  }
  return d;
}

bool cameraFlagsGiven(const OptionFlags& f) {
  return !f.cameraRegions.empty() || f.viewDistance != 0 || !f.cameraVisibility.empty() || f.cameraSpacing != 0 ||
         f.cameraRays != 0;
}

BakeOptions optionsOf(const OptionFlags& f) {
  BakeOptions o;
  o.closed = parseOption<ClosedMode>(f.closed, "--closed");
  o.exit = parseOption<ExitMode>(f.exit, "--exit");
  o.cull = f.cull == "on";
  o.compress = parseOption<CompressMode>(f.compress, "--compress");
  o.undefinedRule = parseOption<UndefinedRule>(f.undefinedRule, "--undefined");
  o.renderer = parseOption<Renderer>(f.renderer, "--renderer");
  o.log2TileSize = log2TileSizeOf(uint64_t(std::max(f.tileSize, 0)), "--tile-size");
  o.receivers = parseOption<ReceiverKind>(f.receivers.substr(0, f.receivers.find(':')), "--receivers");
  if (o.receivers != ReceiverKind::Everywhere) {
    checkPcfWidth(f.receiverPcf);
    o.receiverPcf = uint8_t(f.receiverPcf);
  }
  return o;
}

std::string receiversJson(const BakeOptions& o, const Hash128& h) {
  if (o.receivers == ReceiverKind::Everywhere) return R"({"kind": "everywhere", "pcf": null, "hash": null})";
  return std::string(R"({"kind": ")") + optionName(o.receivers) + R"(", "pcf": )" + std::to_string(o.receiverPcf) +
         R"(, "hash": ")" + h.hex() + "\"}";
}

std::string receiversText(const BakeOptions& o, const Hash128& h) {
  if (o.receivers == ReceiverKind::Everywhere) return "everywhere";
  return std::string(optionName(o.receivers)) + ", PCF up to " + std::to_string(o.receiverPcf) + " (declaration " +
         h.hex() + "); lookups elsewhere may be wrong";
}

}  // namespace cpvs::cli
