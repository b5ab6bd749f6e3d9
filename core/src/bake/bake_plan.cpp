#include "cpvs/bake/bake_plan.h"

#include <optional>

#include "cpvs/bake/camera_views.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "cpvs/base/text.h"
#include "cpvs/bake/tile_plan.h"
#include "cpvs/bake/bake_lights.h"
#include "cpvs/light/area_light.h"

namespace cpvs {

namespace {

std::string vecJson(const Vec3& v) {
  return "[" + jsonNumber(v.x) + ", " + jsonNumber(v.y) + ", " + jsonNumber(v.z) + "]";
}

std::string percent(double share) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f %%", 100 * share);
  return b;
}

// {"cells": N, "rows": [N rows of N/4 hex digits, the first cell the highest bit]}, or null.
std::string coverageJson(const BakePlan& p) {
  if (p.coverageCells == 0) return "null";
  static constexpr char kHex[] = "0123456789abcdef";
  std::string o = "{\"cells\": " + std::to_string(p.coverageCells) + ", \"rows\": [";
  for (uint32_t y = 0; y < p.coverageCells; ++y) {
    o += y ? ", \"" : "\"";
    for (uint32_t x = 0; x < p.coverageCells; x += 4) {
      int digit = 0;
      for (uint32_t k = 0; k < 4; ++k)
        digit = 2 * digit + (x + k < p.coverageCells && p.coverage[size_t(y) * p.coverageCells + x + k] ? 1 : 0);
      o += kHex[digit];
    }
    o += "\"";
  }
  return o + "]}";
}

}  // namespace

bool planCoverage(const std::string& json, uint64_t resolution, uint32_t& cells, std::vector<uint8_t>& coverage) {
  cells = 0;
  coverage.clear();
  const std::string key = "\"coverage\": {\"cells\": ";
  const size_t at = json.find(key);
  if (at == std::string::npos) return false;
  size_t i = at + key.size();
  uint32_t n = 0;
  while (i < json.size() && json[i] >= '0' && json[i] <= '9' && n <= kPlanCoverageCells) n = 10 * n + uint32_t(json[i++] - '0');
  const std::string rows = ", \"rows\": [";
  if (n != std::min<uint64_t>(kPlanCoverageCells, resolution) || json.compare(i, rows.size(), rows) != 0) return false;
  i += rows.size();
  std::vector<uint8_t> bits(size_t(n) * n, 0);
  const uint32_t digits = (n + 3) / 4;
  for (uint32_t y = 0; y < n; ++y) {
    if (y && json.compare(i, 2, ", ") == 0) i += 2;
    if (i + digits + 2 > json.size() || json[i] != '"' || json[i + 1 + digits] != '"') return false;
    for (uint32_t k = 0; k < digits; ++k) {
      const char c = json[i + 1 + k];
      const int v = c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : -1;
      if (v < 0) return false;
      for (uint32_t b = 0; b < 4 && 4 * k + b < n; ++b) bits[size_t(y) * n + 4 * k + b] = uint8_t((v >> (3 - b)) & 1);
    }
    i += digits + 2;
  }
  if (json.compare(i, 2, "]}") != 0) return false;
  cells = n;
  coverage = std::move(bits);
  return true;
}

BakePlan planBake(const Scene& scene, const SceneStats& stats, const BakeOptions& o, const ReceiverDeclaration& d,
                  const RasterScene& raster, const ReceiverSet& reads, std::vector<BakePlan::Medium> media) {
  const OrthoGrid& grid = raster.grid();
  BakePlan p;
  p.scene = scene.name;
  p.triangles = scene.triangleCount();
  // Closed parts as the bake finds them: in the casters (the opaque part, classified again).
  SceneStats opaqueStats;
  std::optional<Scene> opaque;
  if (hasTranslucentMeshes(scene)) opaque = opaquePart(scene, &opaqueStats);
  const SceneStats& castStats = opaque ? opaqueStats : stats;
  p.parts = castStats.parts;
  p.closedParts = castStats.closedParts;
  p.closedTriangles = castStats.closedTriangles;
  // The surfaces that receive (everywhere: not counted).
  const std::vector<uint8_t> sides = d.kind == ReceiverKind::Everywhere ? std::vector<uint8_t>(scene.triangleCount())
                                                                         : receivingSides(scene, d);
  double area = 0, closedArea = 0, walkableArea = 0, receivingArea = 0;
  if (opaque)
    for (size_t t = 0; t < opaque->triangleCount(); ++t)
      if (opaque->closed[t]) closedArea += triangleArea(*opaque, t);
  for (size_t t = 0; t < scene.triangleCount(); ++t) {
    const double at = triangleArea(scene, t);
    area += at;
    if (!opaque && scene.closed[t]) closedArea += at;
    if (walkable(scene, d, t)) walkableArea += at, ++p.walkableTriangles;
    const int receiving = (sides[t] & 1) + (sides[t] >> 1 & 1);
    receivingArea += receiving * at;
    p.receivingSides += uint64_t(receiving);
  }
  p.closedAreaShare = area > 0 ? closedArea / area : 0;
  p.walkableAreaShare = area > 0 ? walkableArea / area : 0;
  p.receivingAreaShare = area > 0 ? receivingArea / area : 0;
  if (d.groundLayer > 0) {
    p.groundLayerFrom = d.groundLayerFrom;
    p.groundLayer = d.groundLayer;
    p.groundSlopeDeg = d.groundSlopeDeg;
  }
  if (d.kind == ReceiverKind::Cameras) {
    p.cameras = true;
    p.cameraVisibility = d.cameraVisibility;
    if (d.cameraVisibility == CameraVisibility::Sampled) {
      p.cameraPositions = uint64_t(cameraPositionCount(d));
      const uint64_t r = cameraRaysPerSide(d);
      p.cameraRays = p.cameraPositions * 6 * r * r;
    }
  }
  p.resolution = grid.resolution();
  p.depthSlices = grid.depthSlices;
  p.receivers = d.kind;
  p.receiverPcf = d.kind == ReceiverKind::Everywhere ? 0 : d.maxPcf;

  const TilePlan tiles(grid.log2Resolution, o.log2TileSize);
  const uint64_t T = uint64_t(1) << tiles.log2TileSize();
  p.tiles = tiles.count();
  p.tileClasses.resize(tiles.count());
  for (uint64_t i = 0; i < tiles.count(); ++i) {
    const TileCoord t = tiles.tile(i);
    p.tileClasses[i] = !raster.touchesRectangle(t.x * T, t.y * T, T, T) ? BakePlan::kUntouched
                       : !reads.touchesRectangle(t.x * T, t.y * T, T, T) ? BakePlan::kUnread
                                                                         : BakePlan::kRendered;
    p.tilesUntouched += p.tileClasses[i] == BakePlan::kUntouched;
    p.tilesUnread += p.tileClasses[i] == BakePlan::kUnread;
  }
  if (d.kind != ReceiverKind::Everywhere) {
    p.coverageCells = uint32_t(std::min<uint64_t>(kPlanCoverageCells, grid.resolution()));
    const uint64_t side = grid.resolution() / p.coverageCells;
    p.coverage.resize(size_t(p.coverageCells) * p.coverageCells);
    for (uint32_t cy = 0; cy < p.coverageCells; ++cy)
      for (uint32_t cx = 0; cx < p.coverageCells; ++cx)
        p.coverage[size_t(cy) * p.coverageCells + cx] = reads.touchesRectangle(cx * side, cy * side, side, side) ? 1 : 0;
  }
  const OrthoGrid coarse = grid.withResolution(std::min(grid.log2Resolution, kLog2PlanColumns));
  p.columnsSampledSide = coarse.resolution();
  if (d.kind != ReceiverKind::Everywhere) {
    const ReceiverSet counted(scene, coarse, d);
    p.columnsReadShare = double(counted.columnsReached()) / double(coarse.resolution() * coarse.resolution());
  }

  for (const SceneLight& l : scene.lights) {
    BakePlan::Light pl{l, false, ""};
    switch (l.type) {
      case SceneLight::Type::Directional: {
        pl.baked = dot(l.direction, grid.frame.dir) > 1 - 1e-9;
        // Six decimals, as a person would type it (a file's float rotation leaves 1e-7s).
        auto typed = [](double v) {
          const double r = std::round(v * 1e6) / 1e6;
          return r == 0 ? 0.0 : r;
        };
        char b[160];
        std::snprintf(b, sizeof b, "bake it with --sun-dir %.6g,%.6g,%.6g (one directional light per bake)",
                      typed(l.direction.x), typed(l.direction.y), typed(l.direction.z));
        pl.reason = pl.baked ? "baked: it is this bake's light" : b;
        break;
      }
      case SceneLight::Type::Point:
      case SceneLight::Type::Spot:
        pl.reason = "not in a sun bake: bake the scene's point and spot lights into a light bundle with --scene-lights";
        break;
      case SceneLight::Type::Area:
        pl.reason = sceneAreaLightHasSize(l)
                        ? "not in a sun bake: bake it into a light bundle with --scene-lights (as " +
                              std::to_string(kDefaultVpls) + " VPLs: soft shadows, query --soft)"
                        : "skipped: the file gives the area light no size";
        break;
      case SceneLight::Type::Ambient:
        pl.reason = "skipped: an ambient light casts no shadow";
        break;
      case SceneLight::Type::Unknown:
        pl.reason = "skipped: a light of a kind assimp does not name";
        break;
    }
    p.lights.push_back(pl);
  }

  for (const SceneMedium& m : scene.media) media.push_back({m.material, "KHR_materials_volume", 0, m.absorption, 0, false, ""});
  for (BakePlan::Medium& m : media) {
    switch (o.receivers) {
      case ReceiverKind::Everywhere:
        m.offered = true;
        m.reason = "offered: light along segments through it (query --segment, render --fog) reads the sun's voxels in "
                   "the air, which this bake holds everywhere";
        break;
      case ReceiverKind::Volume:
      case ReceiverKind::Cameras:
        m.offered = true;
        m.reason = "offered inside the declared volume only: elsewhere the air is left undefined";
        break;
      default:
        m.reason = std::string("not offered: receivers '") + optionName(o.receivers) +
                   "' leave the air undefined (bake for receivers everywhere, or a volume holding the medium)";
        break;
    }
  }
  p.media = std::move(media);
  for (const SceneMesh& m : scene.meshes)
    if (m.triangles > 0 && isTranslucent(m)) {
      ++p.translucentMeshes;
      p.translucentTriangles += m.triangles;
    }

  const bool closedUsed = o.closed == ClosedMode::On || (o.closed == ClosedMode::Auto && p.closedTriangles > 0);
  const uint64_t rendered = p.tiles - p.tilesUntouched - p.tilesUnread;
  auto pass = [&](const char* name, bool runs, std::string why) { p.passes.push_back({name, runs, std::move(why)}); };
  pass("render", rendered > 0,
       std::to_string(rendered) + " of " + std::to_string(p.tiles) + " tiles, " + optionName(o.renderer) +
           (o.renderer == Renderer::Raster ? " (exact rasterization)" : " (a ray per texel)"));
  pass("exit", closedUsed,
       closedUsed ? (o.closed == ClosedMode::On ? std::string("every triangle treated as closed (--closed on)")
                                                 : std::to_string(p.closedParts) + " closed parts, " +
                                                       percent(p.closedAreaShare) + " of the area: their interiors are free") +
                        ", exit depth " + optionName(o.exit)
                  : std::string(o.closed == ClosedMode::Off ? "closed parts ignored (--closed off)" : "no closed part") +
                        ": the first crossing decides every texel" +
                        (o.renderer == Renderer::Embree ? " (first hits only are traced)"
                                                        : " (the rasterizer keeps the nearest crossing only)"));
  pass("receivers", d.kind != ReceiverKind::Everywhere,
       d.kind == ReceiverKind::Everywhere
           ? std::string("receivers everywhere: every voxel outside closed parts is kept")
           : std::string(optionName(d.kind)) + ", PCF up to " + std::to_string(d.maxPcf) + ": lookups reach " +
                 percent(p.columnsReadShare) + " of the columns; " + std::to_string(p.tilesUnread) +
                 " touched tiles are read by none");
  pass("masks", rendered > 0, std::string("undefined voxels by the ") + optionName(o.undefinedRule) + " rule");
  pass("insert", true, o.cull ? "culling identical nodes (§3.2)" : "no culling");
  pass("compress", o.compress != CompressMode::None, std::string(optionName(o.compress)));
  pass("merge", p.tiles > 1, std::to_string(p.tiles) + " tile" + (p.tiles == 1 ? "" : "s"));
  return p;
}

std::string planJson(const BakePlan& p) {
  std::ostringstream o;
  // No scene name: the farm names its copy by hash; the file records the scene's hash.
  o << "{\"triangles\": " << p.triangles << ", \"parts\": " << p.parts
    << ", \"closed_parts\": " << p.closedParts << ", \"closed_triangles\": " << p.closedTriangles
    << ", \"closed_area_share\": " << jsonNumber(p.closedAreaShare) << ", \"resolution\": " << p.resolution
    << ", \"receivers\": {\"kind\": " << jsonString(optionName(p.receivers))
    << ", \"pcf\": " << (p.receiverPcf ? std::to_string(p.receiverPcf) : "null")
    << ", \"columns_read_share\": " << jsonNumber(p.columnsReadShare) << ", \"counted_at\": " << p.columnsSampledSide
    << ", \"ground_layer\": ";
  if (p.groundLayer > 0)
    o << "{\"from\": " << jsonNumber(p.groundLayerFrom) << ", \"to\": " << jsonNumber(p.groundLayer)
      << ", \"slope_deg\": " << jsonNumber(p.groundSlopeDeg) << ", \"walkable_triangles\": " << p.walkableTriangles
      << ", \"walkable_area_share\": " << jsonNumber(p.walkableAreaShare) << "}";
  else
    o << "null";
  if (p.receivers != ReceiverKind::Everywhere)
    o << ", \"receiving_sides\": " << p.receivingSides << ", \"receiving_area_share\": " << jsonNumber(p.receivingAreaShare);
  if (p.cameras)
    o << ", \"cameras\": {\"visibility\": " << jsonString(optionName(p.cameraVisibility))
      << ", \"positions\": " << p.cameraPositions << ", \"rays\": " << p.cameraRays << "}";
  o << "}, \"coverage\": " << coverageJson(p) << ", \"tiles\": {\"total\": " << p.tiles
    << ", \"untouched\": " << p.tilesUntouched << ", \"unread\": " << p.tilesUnread << "}, \"lights\": [";
  for (size_t i = 0; i < p.lights.size(); ++i) {
    const BakePlan::Light& l = p.lights[i];
    o << (i ? ", " : "") << "{\"name\": " << jsonString(l.light.name) << ", \"type\": " << jsonString(lightTypeName(l.light.type))
      << ", \"position\": " << vecJson(l.light.position) << ", \"direction\": " << vecJson(l.light.direction)
      << ", \"baked\": " << (l.baked ? "true" : "false") << ", \"reason\": " << jsonString(l.reason) << "}";
  }
  o << "], \"media\": [";
  for (size_t i = 0; i < p.media.size(); ++i) {
    const BakePlan::Medium& m = p.media[i];
    o << (i ? ", " : "") << "{\"name\": " << jsonString(m.name) << ", \"source\": " << jsonString(m.source)
      << ", \"scattering\": " << jsonNumber(m.scattering) << ", \"absorption\": " << jsonNumber(m.absorption)
      << ", \"g\": " << jsonNumber(m.g) << ", \"offered\": " << (m.offered ? "true" : "false")
      << ", \"reason\": " << jsonString(m.reason) << "}";
  }
  o << "]";
  if (p.translucentMeshes)
    o << ", \"translucent\": {\"meshes\": " << p.translucentMeshes << ", \"triangles\": " << p.translucentTriangles << "}";
  o << ", \"passes\": [";
  for (size_t i = 0; i < p.passes.size(); ++i)
    o << (i ? ", " : "") << "{\"name\": " << jsonString(p.passes[i].name) << ", \"runs\": " << (p.passes[i].runs ? "true" : "false")
      << ", \"why\": " << jsonString(p.passes[i].why) << "}";
  o << "]}";
  return o.str();
}

std::string planText(const BakePlan& p) {
  std::ostringstream o;
  o << p.scene << ": " << p.triangles << " triangles in " << p.parts << " parts; " << p.closedParts
    << " closed parts (" << p.closedTriangles << " triangles, " << percent(p.closedAreaShare) << " of the area)\n";
  o << "  grid " << p.resolution;
  if (p.depthSlices != 0) o << "^2 x " << p.depthSlices << " depth slices";
  else o << "^3";
  o << ", " << p.tiles << " tiles: " << p.tilesUntouched << " touched by no triangle, "
    << p.tilesUnread << " read by no receiver, " << (p.tiles - p.tilesUntouched - p.tilesUnread) << " to render\n";
  o << "  receivers " << optionName(p.receivers);
  if (p.receivers != ReceiverKind::Everywhere)
    o << ", PCF up to " << p.receiverPcf << ": their lookups reach " << percent(p.columnsReadShare)
      << " of the texel columns (counted at " << p.columnsSampledSide << "^2); the rest is free";
  if (p.receivers != ReceiverKind::Everywhere)
    o << "\n  receiving surfaces: " << p.receivingSides << " triangle sides, their area " << percent(p.receivingAreaShare)
      << " of the scene's (both sides of a triangle count: two-sided receivers can pass 100 %)";
  if (p.cameras && p.cameraVisibility == CameraVisibility::Sampled)
    o << "\n  cameras, sampled: the sides " << p.cameraRays << " rays from " << p.cameraPositions
      << " positions hit first (sides seen only between samples are missed: verify measures it)";
  else if (p.cameras)
    o << "\n  cameras, faced: every side a camera place faces within the view distance (occluders ignored)";
  if (p.groundLayer > 0)
    o << "\n  ground layer: from " << p.groundLayerFrom << " to " << p.groundLayer << " scene units above "
      << p.walkableTriangles << " walkable triangles (facing up within " << p.groundSlopeDeg << " degrees; "
      << percent(p.walkableAreaShare) << " of the area)";
  if (p.coverageCells)
    o << "\n  receiver coverage: " << std::count(p.coverage.begin(), p.coverage.end(), 1) << " of "
      << p.coverage.size() << " cells of " << p.resolution / p.coverageCells << "^2 texels can be read"
      << " (recorded in the file: a lookup elsewhere is outside the declared receivers)";
  o << "\n  lights in the file: " << (p.lights.empty() ? "none" : std::to_string(p.lights.size())) << "\n";
  for (const BakePlan::Light& l : p.lights)
    o << "    " << lightTypeName(l.light.type) << " '" << loggable(l.light.name) << "': " << l.reason << "\n";
  if (p.media.empty()) o << "  participating media: none declared (nothing to offer, nothing baked for one)\n";
  else o << "  participating media: " << p.media.size() << " (nothing is baked for them)\n";
  for (const BakePlan::Medium& m : p.media)
    o << "    " << m.source << " '" << loggable(m.name) << "' (scattering " << m.scattering << ", absorption "
      << m.absorption << ", g " << m.g << "): " << m.reason << "\n";
  if (p.translucentMeshes)
    o << "  translucent casters: " << p.translucentMeshes << " meshes, " << p.translucentTriangles
      << " triangles: left out of the CPVS; a TOP tree of their shadow frusta beside it darkens what lies behind them "
         "by their transmittance (front-face culling off)\n";
  else
    o << "  translucent casters: none (no glTF transmission or alpha blend, no OBJ or IFC opacity below 1): nothing beside "
         "the CPVS\n";
  o << "  passes:\n";
  for (const BakePlan::Pass& s : p.passes) o << "    " << (s.runs ? "runs   " : "skipped") << "  " << s.name << ": " << s.why << "\n";
  return o.str();
}

}  // namespace cpvs
