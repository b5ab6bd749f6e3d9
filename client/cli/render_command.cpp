// `cpvs render`: a picture of the scene in the sun with the baked shadows, optionally next
// to exact ray-traced shadows and their difference.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>

#include "cli_util.h"
#include "commands.h"
#include "cpvs/base/error.h"
#include "cpvs/base/parse.h"
#include "cpvs/base/progress.h"
#include "cpvs/eval/light_render.h"
#include "cpvs/eval/render.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/io/dmh_file.h"
#include "cpvs/query/dag_mh_query.h"
#include "cpvs/query/light_tiles.h"
#include "cpvs/runtime/runtime.h"
#include "cpvs/scene/source.h"

namespace cpvs::cli {

namespace {

struct RenderArgs {
  std::string file, scene, camera, out, fog, dynamic, size = "960x600";
  int pcf = 3, frames = 1, delayMs = 120;
  bool reference = false, gpu = false;
};

// --dynamic MESH[:TRANSFORM]: a mesh that moves over the baked scene, and where it is.
struct DynamicFlag {
  std::string mesh;
  std::vector<double> placement;  // empty, X,Y,Z[,SCALE[,YAW_DEG]] or a row-major 3x4 matrix
};

DynamicFlag parseDynamic(const std::string& text) {
  DynamicFlag d{text, {}};
  const size_t colon = text.rfind(':');
  if (colon == std::string::npos) return d;
  // The part after the last ':' is a placement when it is a list of numbers (a scene name
  // like city:3 has one number and stays whole).
  std::vector<double> numbers;
  try {
    numbers = parseNumbers(text.substr(colon + 1), "--dynamic");
  } catch (const InputError&) {
    return d;
  }
  if (numbers.size() < 3) return d;
  if (numbers.size() > 5 && numbers.size() != 12)
    throw InputError("--dynamic '" + text + "': a placement is X,Y,Z[,SCALE[,YAW_DEG]] or 12 numbers (a 3x4 matrix)");
  for (double v : numbers)
    if (!std::isfinite(v)) throw InputError("--dynamic '" + text + "': the placement is not finite");
  if (numbers.size() >= 4 && !(numbers[3] > 0)) throw InputError("--dynamic '" + text + "': the scale must be positive");
  d.mesh = text.substr(0, colon);
  d.placement = std::move(numbers);
  return d;
}

/// Where the caster is in frame k of n: the placement given (or, by default, 15 % of the
/// scene's width, floating over its centre a tenth of its height above its top), turned and
/// carried across a third of the scene over the frames.
std::array<double, 12> casterTransform(const DynamicFlag& flag, const Scene& mesh, const Scene& scene, int k, int n) {
  Vec3 mlo, mhi, lo, hi;
  sceneBounds(mesh, mlo, mhi);
  sceneBounds(scene, lo, hi);
  std::array<double, 12> m{};
  if (flag.placement.size() == 12) {
    std::copy(flag.placement.begin(), flag.placement.end(), m.begin());
    return m;
  }
  const Vec3 size = hi - lo, msize = mhi - mlo;
  Vec3 at{0.5 * (lo.x + hi.x), hi.y + 0.1 * size.y, 0.5 * (lo.z + hi.z)};
  double scale = 0.15 * std::max(size.x, size.z) / std::max({msize.x, msize.y, msize.z, 1e-300});
  double yaw = 0;
  if (!flag.placement.empty()) at = {flag.placement[0], flag.placement[1], flag.placement[2]};
  if (flag.placement.size() >= 4) scale = flag.placement[3];
  if (flag.placement.size() >= 5) yaw = flag.placement[4] * M_PI / 180;
  const double f = n > 1 ? double(k) / double(n - 1) - 0.5 : 0;
  at.x += f * size.x / 3;
  yaw += f * M_PI;
  // The mesh's base centre (its bounding box's bottom middle) goes to `at`.
  const Vec3 base{0.5 * (mlo.x + mhi.x), mlo.y, 0.5 * (mlo.z + mhi.z)};
  const double c = std::cos(yaw) * scale, s = std::sin(yaw) * scale;
  m = {c, 0, s, 0, 0, scale, 0, 0, -s, 0, c, 0};
  m[3] = at.x - (m[0] * base.x + m[1] * base.y + m[2] * base.z);
  m[7] = at.y - (m[4] * base.x + m[5] * base.y + m[6] * base.z);
  m[11] = at.z - (m[8] * base.x + m[9] * base.y + m[10] * base.z);
  return m;
}

/// The scene with the caster placed in it: what the camera and the exact rays see.
Scene withCaster(const Scene& scene, const runtime::CasterMesh& caster) {
  Scene s = scene;
  const uint32_t base = uint32_t(s.positions.size());
  for (const Vec3& p : caster.positions) s.positions.push_back(caster.place(p));
  for (uint32_t i : caster.indices) s.indices.push_back(base + i);
  for (size_t t = 0; t < caster.indices.size() / 3; ++t) s.closed.push_back(caster.closed.empty() ? 0 : caster.closed[t]);
  s.meshes.clear();
  return s;
}

// The surfaces the camera's pixels see: their points and normals, and which pixel each is.
struct SeenSurfaces {
  std::vector<Vec3> points, normals;
  std::vector<size_t> at;
  explicit SeenSurfaces(const CameraHits& hits) {
    for (size_t i = 0; i < hits.pixels.size(); ++i)
      if (hits.pixels[i].hit) {
        points.push_back(hits.pixels[i].point);
        normals.push_back(hits.pixels[i].normal);
        at.push_back(i);
      }
  }
};

// The visibility of every pixel that sees a surface, looked up on a Vulkan device.
std::vector<float> gpuVisibility(const CameraHits& hits, runtime::ShadowLookups& lookups, int pcf) {
  const SeenSurfaces seenBy(hits);
  std::vector<float> seen, vis(hits.pixels.size(), 1.0f);
  lookups.visibility(seenBy.points, seenBy.normals, pcf, seen);
  for (size_t k = 0; k < seenBy.at.size(); ++k) vis[seenBy.at[k]] = seen[k];
  return vis;
}

// The light let through the artifact's translucent casters at every pixel that sees a
// surface (white elsewhere), on the device when there is one.
std::vector<std::array<float, 3>> pixelTransmittance(const CameraHits& hits, const runtime::ShadowArtifact& artifact,
                                                     runtime::ShadowLookups* gpu) {
  const SeenSurfaces seenBy(hits);
  std::vector<std::array<float, 3>> seen, out(hits.pixels.size(), {1, 1, 1});
  if (gpu) gpu->transmittance(seenBy.points, seenBy.normals, seen);
  else runtime::cpuTransmittance(artifact, seenBy.points, seenBy.normals, seen);
  for (size_t k = 0; k < seenBy.at.size(); ++k) out[seenBy.at[k]] = seen[k];
  return out;
}

void parseSize(const std::string& text, int& w, int& h) {
  size_t x = text.find('x');
  auto bad = [&] { return InputError("--size '" + text + "': expected WIDTHxHEIGHT, e.g. 960x600"); };
  if (x == std::string::npos) throw bad();
  try {
    size_t used = 0;
    w = std::stoi(text.substr(0, x), &used);
    if (used != x) throw bad();
    h = std::stoi(text.substr(x + 1), &used);
    if (used != text.size() - x - 1) throw bad();
  } catch (const std::logic_error&) {
    throw bad();
  }
  if (w < 1 || h < 1 || w > 16384 || h > 16384) throw InputError("--size '" + text + "': each side must be 1..16384");
}

/// Writes `base`.exr and `base`.png.
void writeBoth(const std::string& base, const Image& img) {
  writeExr(base + ".exr", img);
  writePng(base + ".png", img);
}

// A light bundle: the scene at night under all its lights, each pixel shaded with the
// lights its 16x16 tile's list holds; NAME-tiles shows how many that is.
int renderBundle(const RenderArgs& a, const std::vector<uint8_t>& bytes, int w, int h, const std::string& base) {
  if (a.reference) throw InputError("--reference compares a sun artifact with exact shadows; verify checks a light bundle");
  const LightBundle bundle = decodeBundle(bytes.data(), bytes.size(), a.file);
  Scene scene = openMatchingScene(a.scene, bundle.sceneHash);
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  const RayScene rays(scene, (lo + hi) * 0.5);
  const BundleQuery q(bundle);
  const Camera cam = a.camera.empty() ? defaultCamera(scene, Vec3{0.35, -1, 0.25}, double(w) / h) : Camera::parse(a.camera);
  const CameraHits hits = traceCamera(scene, rays, cam, w, h);
  std::vector<Vec3> points;
  std::vector<uint8_t> hit;
  hitPoints(hits, points, hit);
  auto start = std::chrono::steady_clock::now();
  const LightTiles tiles = cullLights(q, points, hit, w, h);
  const double cull = secondsSince(start);
  start = std::chrono::steady_clock::now();
  std::string where = "on the CPU";
  if (a.gpu) {
    // The same lookups on a device, shaded with its answers: the CPU's picture, bit for bit.
    auto artifact = std::make_shared<const runtime::LightArtifact>(bundle);
    auto device = runtime::GpuDevice::create();
    runtime::GpuLights lights(*device, artifact);
    std::vector<uint32_t> which, lit;
    std::vector<Vec3> at, normals;
    tileLookups(hits, tiles, which, at, normals);
    // A VPL's lookup is its area light's soft visibility, once a pixel for all its VPLs.
    std::vector<uint32_t> hardLights, softAreas;
    std::vector<Vec3> hardAt, hardNormals, softAt, softNormals;
    std::vector<int64_t> lookup(which.size());  // >= 0: a hard lookup's index, < 0: -1 - a soft one's
    std::vector<int64_t> lastSoft(q.areaCount(), -1);
    for (size_t i = 0; i < which.size(); ++i) {
      const uint32_t area = q.light(which[i]).light.area;
      if (area == 0) {
        lookup[i] = int64_t(hardLights.size());
        hardLights.push_back(which[i]), hardAt.push_back(at[i]), hardNormals.push_back(normals[i]);
        continue;
      }
      int64_t& last = lastSoft[area - 1];
      if (last < 0 || !(softAt[size_t(last)] == at[i]) || !(softNormals[size_t(last)] == normals[i])) {
        last = int64_t(softAreas.size());
        softAreas.push_back(area - 1), softAt.push_back(at[i]), softNormals.push_back(normals[i]);
      }
      lookup[i] = -1 - last;
    }
    std::vector<float> soft;
    if (!hardLights.empty()) lights.litTexels(hardLights, hardAt, hardNormals, a.pcf, lit);
    if (!softAreas.empty()) lights.softVisibility(softAreas, softAt, softNormals, soft);
    std::vector<float> visibility(which.size());
    for (size_t i = 0; i < which.size(); ++i)
      visibility[i] = lookup[i] >= 0 ? float(lit[size_t(lookup[i])]) / float(a.pcf * a.pcf) : soft[size_t(-1 - lookup[i])];
    writeBoth(base, shadeLightTiles(hits, q, tiles, visibility));
    where = "lookups on " + device->name();
  } else {
    writeBoth(base, shadeLightTiles(hits, q, tiles, a.pcf));
  }
  const double shade = secondsSince(start);
  // Lights per tile, black (none) to white (the longest list).
  Image heat(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t t = tiles.tile(x, y);
      const float v = tiles.longest ? float(tiles.begin[t + 1] - tiles.begin[t]) / float(tiles.longest) : 0.0f;
      heat.at(x, y) = {v, v * v, 0.25f * v};
    }
  writePng(base + "-tiles.png", heat);
  const size_t tileCount = tiles.begin.size() - 1;
  std::printf("Wrote %s.png and %s.exr (%zu lights, PCF %d, %s) and %s-tiles.png (lights per tile)\n",
              base.c_str(), base.c_str(), q.lightCount(), a.pcf, where.c_str(), base.c_str());
  std::printf("  %zu tiles of 16x16: %.1f lights per tile on average, at most %u; %llu over a list of %u; culling %.3f s, "
              "shading %.3f s\n",
              tileCount, double(tiles.lights.size()) / double(std::max<size_t>(1, tileCount)), tiles.longest,
              static_cast<unsigned long long>(tiles.overflowing), tiles.capacity, cull, shade);
  std::printf("Camera: %.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n", cam.eye.x, cam.eye.y, cam.eye.z, cam.target.x,
              cam.target.y, cam.target.z, cam.fovDeg);
  return 0;
}

// A caster that moves over the baked scene: each frame the scene with the caster placed
// in it, seen by the camera, its pixels lit by the CPVS times the caster's TOP tree
// (ShadowLookups with DynamicCasters); with --reference the same frame with exact rays.
int renderDynamic(const RenderArgs& a, const Scene& scene, const OrthoGrid& grid,
                  const std::shared_ptr<const runtime::ShadowArtifact>& artifact, runtime::ShadowLookups* gpu,
                  const Camera& cam, int w, int h, const std::string& base) {
  const DynamicFlag flag = parseDynamic(a.dynamic);
  SceneStats stats;
  const Scene mesh = openScene(flag.mesh, &stats);
  if (mesh.triangleCount() == 0) throw InputError("--dynamic: " + flag.mesh + " has no triangles");
  runtime::ShadowLookups cpu(artifact, runtime::Backend::Cpu);
  runtime::ShadowLookups& lookups = gpu ? *gpu : cpu;
  const Vec3 L = grid.frame.dir;
  std::vector<Image> frames;
  double build = 0;
  size_t frusta = 0;
  uint64_t compared = 0, differing = 0;
  for (int k = 0; k < a.frames; ++k) {
    const runtime::CasterMesh caster{mesh.positions, mesh.indices, mesh.closed,
                                     casterTransform(flag, mesh, scene, k, a.frames)};
    const auto start = std::chrono::steady_clock::now();
    // With --gpu the frusta are inserted into their tree on the device.
    auto casters = std::make_shared<const runtime::DynamicCasters>(
        *artifact, std::vector<runtime::CasterMesh>{caster}, -1,
        gpu ? runtime::DynamicCasters::Build::Device : runtime::DynamicCasters::Build::Cpu);
    build += secondsSince(start);
    frusta = casters->tree().frustumCount();
    lookups.setDynamicCasters(casters);
    const Scene placed = withCaster(scene, caster);
    const RayScene rays(placed, grid.origin);
    const CameraHits hits = traceCamera(placed, rays, cam, w, h);
    const std::vector<float> vis = gpuVisibility(hits, lookups, a.pcf);
    frames.push_back(shadeHits(hits, vis, L));
    if (k == 0) {
      writeBoth(base, frames.back());
      if (a.reference) {
        const std::vector<float> exact = exactVisibility(hits, rays, grid);
        writeBoth(base + "-reference", shadeHits(hits, exact, L));
        const std::vector<float> binary = a.pcf == 1 ? vis : gpuVisibility(hits, lookups, 1);
        writeBoth(base + "-diff", differenceImage(hits, binary, exact, L, &compared, &differing));
      }
    }
  }
  std::printf("Wrote %s.png and %s.exr (CPVS shadows times a dynamic caster's, PCF %d, looked up on %s)\n", base.c_str(),
              base.c_str(), a.pcf, lookups.deviceName().c_str());
  std::printf("  caster: %s, %zu triangles, %zu shadow frusta; its TOP tree built in %.2f ms a frame\n", flag.mesh.c_str(),
              mesh.triangleCount(), frusta, 1e3 * build / a.frames);
  if (a.reference) {
    std::printf("Wrote %s-reference.png/.exr (exact ray-traced shadows, the caster included) and %s-diff.png/.exr\n",
                base.c_str(), base.c_str());
    std::printf("  %llu of %llu sunward pixels differ (%.3f%%): red = darker than exact, blue = brighter\n",
                static_cast<unsigned long long>(differing), static_cast<unsigned long long>(compared),
                compared ? 100.0 * double(differing) / double(compared) : 0.0);
  }
  if (a.frames > 1) {
    writeAnimatedPng(base + "-animation.png", frames, a.delayMs);
    std::printf("Wrote %s-animation.png: %d frames of the caster crossing the scene, %d ms each\n", base.c_str(), a.frames,
                a.delayMs);
  }
  std::printf("Camera: %.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n", cam.eye.x, cam.eye.y, cam.eye.z, cam.target.x,
              cam.target.y, cam.target.z, cam.fovDeg);
  return 0;
}

// The difference picture of binary lookups against the exact shadows, written and said.
void writeDifference(const std::string& base, const CameraHits& hits, const std::vector<float>& binary,
                     const std::vector<float>& exact, const Vec3& lightDir, const char* kind) {
  uint64_t compared = 0, differing = 0;
  writeBoth(base + "-diff", differenceImage(hits, binary, exact, lightDir, &compared, &differing));
  std::printf("Wrote %s-reference.png/.exr (exact ray-traced shadows) and %s-diff.png/.exr\n", base.c_str(), base.c_str());
  std::printf("  %llu of %llu sunward pixels differ (%.3f%%): red = %s darker, blue = %s brighter\n",
              static_cast<unsigned long long>(differing), static_cast<unsigned long long>(compared),
              compared ? 100.0 * double(differing) / double(compared) : 0.0, kind, kind);
}

void printCamera(const Camera& cam) {
  std::printf("Camera: %.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n", cam.eye.x, cam.eye.y, cam.eye.z, cam.target.x,
              cam.target.y, cam.target.z, cam.fovDeg);
}

// A DAG-MH: its shadows on the CPU or (--gpu) the runtime's device, and with --reference
// the exact ones and where they differ.
int renderDagMh(const RenderArgs& a, const std::vector<uint8_t>& bytes, int w, int h, const std::string& base) {
  if (!a.fog.empty() || !a.dynamic.empty()) throw InputError("--fog and --dynamic are drawn with a .cpvs, not a DAG-MH");
  DmhArtifact art = decodeDmh(bytes.data(), bytes.size(), a.file);
  std::optional<Scene> opaque;
  const Scene scene = openMatchingScene(a.scene, art.sceneHash);
  const Scene& drawn = sunCasters(scene, opaque);
  const RayScene rays(drawn, art.grid.origin);
  const OrthoGrid grid = art.grid;
  const Vec3 L = grid.frame.dir;
  auto artifact = std::make_shared<const runtime::ShadowArtifact>(DagMhQuery(art.grid, std::move(art.dag)));
  const DagMhQuery& q = artifact->dagMh();
  std::unique_ptr<runtime::ShadowLookups> gpu;
  if (a.gpu) gpu = std::make_unique<runtime::ShadowLookups>(artifact, runtime::Backend::Gpu);
  const Camera cam = a.camera.empty() ? defaultCamera(drawn, L, double(w) / h) : Camera::parse(a.camera);
  const CameraHits hits = traceCamera(drawn, rays, cam, w, h);
  auto lookup = [&](int pcf) { return gpu ? gpuVisibility(hits, *gpu, pcf) : lookupVisibility(hits, q, pcf); };
  const std::vector<float> vis = lookup(a.pcf);
  writeBoth(base, shadeHits(hits, vis, L));
  std::printf("Wrote %s.png and %s.exr (DAG-MH shadows, PCF %d, looked up on %s)\n", base.c_str(), base.c_str(), a.pcf,
              gpu ? gpu->deviceName().c_str() : "the CPU");
  if (a.reference) {
    const std::vector<float> exact = exactVisibility(hits, rays, grid);
    writeBoth(base + "-reference", shadeHits(hits, exact, L));
    writeDifference(base, hits, a.pcf == 1 ? vis : lookup(1), exact, L, "DAG-MH");
  }
  printCamera(cam);
  return 0;
}

int runRender(const RenderArgs& a) {
  int w = 0, h = 0;
  parseSize(a.size, w, h);
  namespace fs = std::filesystem;
  fs::path out(a.out);
  std::string ext = out.extension().string();
  if (ext != ".png" && ext != ".exr" && !ext.empty())
    throw InputError("--out '" + a.out + "': name an image .png or .exr (both are written)");
  std::string base = (out.parent_path() / out.stem()).string();
  checkOutputFolder(a.out, "--out");

  const std::vector<uint8_t> bytes = readFile(a.file);
  if (isDmh(bytes.data(), bytes.size())) return renderDagMh(a, bytes, w, h, base);
  std::optional<Medium> fog;
  if (!a.fog.empty()) fog = parseMedium(a.fog, "--fog");
  if (cpvsFormatVersion(bytes.data(), bytes.size(), a.file) == kBundleFormatVersion) {
    if (fog) throw InputError("--fog: the fog is lit by the sun; " + a.file + " is a light bundle");
    return renderBundle(a, bytes, w, h, base);
  }
  if (!a.dynamic.empty() && fog) throw InputError("--dynamic and --fog: one at a time");
  if (a.dynamic.empty() && a.frames != 1) throw InputError("--frames: the frames of a --dynamic caster's path");
  CpvsArtifact art = decodeCpvs(bytes.data(), bytes.size(), a.file);
  if (fog) checkGridInTheAir(art, a.file, "--fog");
  Scene scene = openMatchingScene(a.scene, art);
  // Translucent casters are not drawn (the camera sees through them); the light they let
  // through tints what lies behind them.
  const bool translucent = art.translucent != nullptr;
  if (translucent) {
    if (!a.dynamic.empty() || fog) throw InputError("--dynamic and --fog draw no light through translucent casters, and " + a.file + " has some: render it without them");
    scene = opaquePart(scene);
    if (scene.triangleCount() == 0)
      throw InputError(a.scene + " is translucent casters only: nothing to draw their light on");
  }
  RayScene rays(scene, art.grid.origin);
  const Vec3 L = art.grid.frame.dir;
  const OrthoGrid grid = art.grid;
  auto artifact =
      std::make_shared<const runtime::ShadowArtifact>(ShadowQuery(art.grid, std::move(art.packed)), std::move(art.translucent));
  const ShadowQuery& q = artifact->cpu();
  std::unique_ptr<runtime::ShadowLookups> gpu;
  if (a.gpu) gpu = std::make_unique<runtime::ShadowLookups>(artifact, runtime::Backend::Gpu);
  Camera cam = a.camera.empty() ? defaultCamera(scene, L, double(w) / h) : Camera::parse(a.camera);
  if (!a.dynamic.empty()) return renderDynamic(a, scene, grid, artifact, gpu.get(), cam, w, h, base);
  CameraHits hits = traceCamera(scene, rays, cam, w, h);
  auto lookup = [&](int pcf) { return gpu ? gpuVisibility(hits, *gpu, pcf) : cpvsVisibility(hits, q, pcf); };
  std::vector<float> vis = lookup(a.pcf);
  if (fog) {
    Vec3 lo, hi;
    sceneBounds(scene, lo, hi);
    const auto start = std::chrono::steady_clock::now();
    std::vector<float> onDevice;
    if (gpu) {
      // The fog's segments walked on the device (float in-scattering: within rounding of
      // the CPU's picture, not its bytes).
      std::vector<Vec3> from, to;
      std::vector<double> lit;
      fogSegments(hits, cam, lo, hi, from, to);
      gpu->segments(from, to, *fog, lit, onDevice);
    }
    writeBoth(base, foggedImage(shadeHits(hits, vis, L), hits, cam, q, *fog, lo, hi, gpu ? &onDevice : nullptr));
    std::printf("Wrote %s.png and %s.exr (CPVS shadows, PCF %d, looked up on %s; sun shafts through the fog "
                "walked on %s in %.2f s)\n", base.c_str(), base.c_str(), a.pcf,
                gpu ? gpu->deviceName().c_str() : "the CPU", gpu ? gpu->deviceName().c_str() : "the CPU",
                secondsSince(start));
  } else {
    std::vector<std::array<float, 3>> tint;
    if (translucent) tint = pixelTransmittance(hits, *artifact, gpu.get());
    writeBoth(base, shadeHits(hits, vis, L, translucent ? &tint : nullptr));
    std::printf("Wrote %s.png and %s.exr (CPVS shadows%s, PCF %d, looked up on %s)\n", base.c_str(), base.c_str(),
                translucent ? " times the light through the translucent casters, which are not drawn" : "", a.pcf,
                gpu ? gpu->deviceName().c_str() : "the CPU");
  }
  if (a.reference) {
    std::vector<float> exact = exactVisibility(hits, rays, grid);
    std::vector<std::array<float, 3>> tint;
    if (translucent) tint = pixelTransmittance(hits, *artifact, nullptr);
    writeBoth(base + "-reference", shadeHits(hits, exact, L, translucent ? &tint : nullptr));
    // The difference compares binary lookups so that a filtered edge is not counted.
    writeDifference(base, hits, a.pcf == 1 ? vis : lookup(1), exact, L, "CPVS");
  }
  printCamera(cam);
  return 0;
}

struct SheetArgs {
  std::string dir, scene, camera, out, animation, size = "320x200";
  int columns = 4, pcf = 3, delayMs = 500;
};

// A contact sheet: every version-*.cpvs of a folder (what `cpvs subscribe` writes), in
// order, rendered from one camera and laid out in rows: the sun moving through a track.
int runSheet(const SheetArgs& a) {
  int w = 0, h = 0;
  parseSize(a.size, w, h);
  if (a.columns < 1 || a.columns > 64) throw InputError("--columns must be 1..64");
  namespace fs = std::filesystem;
  checkOutputFolder(a.out, "--out");
  std::vector<fs::path> files;
  if (!fs::is_directory(a.dir)) throw InputError(a.dir + " is not a folder");
  for (const auto& e : fs::directory_iterator(a.dir))
    if (e.path().extension() == ".cpvs" && e.path().filename().string().rfind("version-", 0) == 0) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  if (files.empty()) throw InputError("no version-*.cpvs files in " + a.dir + " (cpvs subscribe writes them)");
  const int cols = std::min<int>(a.columns, int(files.size())), rows = int((files.size() + size_t(cols) - 1) / size_t(cols));
  Image sheet;
  sheet.width = cols * w;
  sheet.height = rows * h;
  sheet.pixels.assign(size_t(sheet.width) * size_t(sheet.height), Rgb{0.1f, 0.1f, 0.1f});
  std::optional<Scene> scene;
  std::optional<Camera> cam;
  std::vector<Image> frames;
  for (size_t k = 0; k < files.size(); ++k) {
    CpvsArtifact art = readCpvs(files[k].string());
    if (!scene) {
      // Translucent casters are not drawn; their light tints the versions that carry them.
      scene = openMatchingScene(a.scene, art);
      if (hasTranslucentMeshes(*scene)) scene = opaquePart(*scene);
    }
    if (!cam) cam = a.camera.empty() ? defaultCamera(*scene, art.grid.frame.dir, double(w) / h) : Camera::parse(a.camera);
    const Vec3 L = art.grid.frame.dir;
    RayScene rays(*scene, art.grid.origin);
    const runtime::ShadowArtifact artifact(ShadowQuery(art.grid, std::move(art.packed)), std::move(art.translucent));
    const CameraHits hits = traceCamera(*scene, rays, *cam, w, h);
    std::vector<std::array<float, 3>> tint;
    if (artifact.translucent()) tint = pixelTransmittance(hits, artifact, nullptr);
    const Image img = shadeHits(hits, cpvsVisibility(hits, artifact.cpu(), a.pcf), L, artifact.translucent() ? &tint : nullptr);
    if (!a.animation.empty()) frames.push_back(img);
    const int x0 = int(k % size_t(cols)) * w, y0 = int(k / size_t(cols)) * h;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) sheet.pixels[size_t(y0 + y) * size_t(sheet.width) + size_t(x0 + x)] = img.pixels[size_t(y) * size_t(w) + size_t(x)];
  }
  writePng(a.out, sheet);
  std::printf("Wrote %s: %zu versions, %d x %d\n", a.out.c_str(), files.size(), sheet.width, sheet.height);
  if (!a.animation.empty()) {
    writeAnimatedPng(a.animation, frames, a.delayMs);
    std::printf("Wrote %s: an animated PNG of %zu frames, %d ms each\n", a.animation.c_str(), frames.size(), a.delayMs);
  }
  return 0;
}

}  // namespace

void addContactSheetCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<SheetArgs>();
  CLI::App* c = app.add_subcommand("contact-sheet",
                                   "One picture of every version a subscription wrote: the sun moving through a track");
  c->add_option("dir", a->dir, "Folder of version-*.cpvs (cpvs subscribe --out)")->required();
  c->add_option("scene", a->scene, "The scene they were baked from (file, city[:BLOCKS[:SEED]] or landscape[:SIZE[:SEED]])")->required();
  c->add_option("--out,-o", a->out, "Output PNG")->required();
  c->add_option("--size", a->size, "Size of each picture WIDTHxHEIGHT")->capture_default_str();
  c->add_option("--columns", a->columns, "Pictures per row")->capture_default_str();
  c->add_option("--camera", a->camera, "EX,EY,EZ,TX,TY,TZ[,FOV] (default: the first version's sunny-side view)");
  c->add_option("--pcf", a->pcf, "Filter width")->check(CLI::IsMember({1, 3, 5, 7, 9}))->capture_default_str();
  c->add_option("--animation", a->animation, "Also write the versions as an animated PNG (APNG), one frame each");
  c->add_option("--delay-ms", a->delayMs, "Milliseconds per frame of the animation")->check(CLI::Range(1, 65535))->capture_default_str();
  c->callback([a, &status] { status = runSheet(*a); });
}

void addRenderCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<RenderArgs>();
  CLI::App* c = app.add_subcommand(
      "render", "Render the scene lit by the sun with the baked shadows, or at night by a light bundle's lights (PNG and EXR)");
  c->add_option("file", a->file, ".cpvs, light bundle or .dmh file")->required();
  c->add_option("scene", a->scene, "The scene it was baked from (file, city[:BLOCKS[:SEED]] or landscape[:SIZE[:SEED]])")->required();
  c->add_option("--out,-o", a->out, "Output image; NAME.png and NAME.exr are both written")->required();
  c->add_option("--camera", a->camera,
                "EX,EY,EZ,TX,TY,TZ[,FOV]: eye, target and vertical field of view in degrees "
                "(default: a three-quarter view from the sunny side)");
  c->add_option("--size", a->size, "Image size WIDTHxHEIGHT")->capture_default_str();
  c->add_option("--pcf", a->pcf, "Filter width in texels: 1, 3, 5, 7 or 9")
      ->check(CLI::IsMember({1, 3, 5, 7, 9}))->capture_default_str();
  c->add_flag("--gpu", a->gpu,
              "Look the shadows up on a Vulkan device (headless; CPVS_DEVICE picks one by name): the same "
              "picture as the CPU's. Exit status 5 when there is none");
  c->add_option("--fog", a->fog,
                 "SIGMA_S,SIGMA_A[,G]: the scene's box filled with a homogeneous medium (scattering and absorption per "
                 "world unit, Henyey-Greenstein g) that the sun lights where the baked voxels are lit: sun shafts. "
                 "Needs a bake for receivers everywhere; with --gpu the fog is walked on the device too");
  c->add_option("--dynamic", a->dynamic,
                "MESH[:X,Y,Z[,SCALE[,YAW_DEG]]] or MESH:M00,...,M23 (12 numbers): a mesh that moves over the baked "
                "scene (a file or a generated scene) and where it stands (its base centre; default: over the scene's "
                "centre, a tenth of its height above its top, 15 % of its width); its exact shadows come from a TOP tree (partitioned "
                "shadow volumes) built each frame, times the baked ones");
  c->add_option("--frames", a->frames, "With --dynamic: frames of the caster crossing the scene (more than 1: also "
                                       "NAME-animation.png, an animated PNG)")
      ->check(CLI::Range(1, 600))
      ->capture_default_str();
  c->add_option("--delay-ms", a->delayMs, "Milliseconds per frame of the animation")
      ->check(CLI::Range(1, 65535))
      ->capture_default_str();
  c->add_flag("--reference", a->reference,
              "Also render exact ray-traced shadows (NAME-reference) and the difference (NAME-diff)");
  c->callback([a, &status] { status = runRender(*a); });
}

}  // namespace cpvs::cli
