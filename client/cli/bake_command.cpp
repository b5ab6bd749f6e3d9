// `cpvs bake`: one process, no server: scene in, .cpvs out, with a summary.
#include <spdlog/spdlog.h>

#include <cstdio>
#include <iostream>
#include <memory>
#include <sstream>

#include <tbb/task_group.h>

#include "bake_flags.h"
#include "bundle_text.h"
#include "cpvs/bake/bake_lights.h"
#include "cpvs/dag/packed_layout.h"
#include "cpvs/bake/camera_views.h"
#include "cpvs/bake/bake_plan.h"
#include "cli_util.h"
#include "commands.h"
#include "cpvs/bake/tile_plan.h"
#include "cpvs/base/parse.h"
#include "cpvs/bake/bake.h"
#include "cpvs/bake/bake_dag_mh.h"
#include "cpvs/io/dmh_file.h"
#include "dag_mh_text.h"
#include "cpvs/bake/tile_cache.h"
#include "cpvs/bake/tile_key.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/psv/translucent_tree.h"
#include "cpvs/scene/source.h"

namespace cpvs::cli {

namespace {

struct BakeArgs {
  std::string scene, out, resolution = "4K", format = "cpvs";
  SunFlags sun;
  LightFlags lights;
  int pointerGrid = kMaxGridLevels;
  OptionFlags options;
  int threads = 0;
  std::string tileCache;
  uint64_t tileCacheMb = 4096;
  bool zstd = true, json = false, quiet = false;
};

std::string summaryJson(const BakeArgs& a, const Scene& scene, const SceneStats& ss, const CpvsArtifact& art,
                        const StageTimes& st, double total, uint64_t tiles, uint64_t fileBytes) {
  const Dag& dag = art.dag;
  uint64_t R = art.grid.resolution();
  std::ostringstream o;
  o << "{\n  \"scene\": " << jsonString(scene.name) << ",\n  \"scene_hash\": " << jsonString(art.sceneHash.hex())
    << ",\n  \"triangles\": " << ss.triangles << ",\n  \"degenerate_dropped\": " << ss.degenerateDropped
    << ",\n  \"closed_triangles\": " << ss.closedTriangles << ",\n  \"resolution\": " << R
    << ",\n  \"light_dir\": [" << jsonNumber(art.grid.frame.dir.x) << ", " << jsonNumber(art.grid.frame.dir.y) << ", "
    << jsonNumber(art.grid.frame.dir.z) << "],\n  \"options\": {\"closed\": " << jsonString(optionName(art.options.closed))
    << ", \"exit\": " << jsonString(optionName(art.options.exit)) << ", \"cull\": " << (art.options.cull ? "true" : "false")
    << ", \"compress\": " << jsonString(optionName(art.options.compress))
    << ", \"undefined\": " << jsonString(optionName(art.options.undefinedRule))
    << ", \"renderer\": " << jsonString(optionName(art.options.renderer))
    << ", \"tile_size\": " << (1u << art.options.log2TileSize) << "},\n  \"receivers\": "
    << receiversJson(art.options, art.receiverHash) << ",\n  \"tiles\": " << tiles << ",\n  \"tiles_skipped\": " << st.tilesSkipped << ",\n  \"tiles_reused\": " << st.tilesReused
    << ",\n  \"bytes\": " << dag.bytes() << ",\n  \"file_bytes\": " << fileBytes
    << ",\n  \"shadow_map_bytes\": " << R * R * 2
    << ",\n  \"ratio_to_shadow_map\": " << jsonNumber(double(R * R * 2) / double(std::max<uint64_t>(1, dag.bytes())))
    << ",\n  \"nodes\": " << dag.nodeCount() << ",\n  \"seconds_total\": " << jsonNumber(total) << ",\n  \"stages\": {";
  bool first = true;
  for (const auto& [k, v] : st.seconds) {
    o << (first ? "" : ", ") << jsonString(k) << ": " << jsonNumber(v);
    first = false;
  }
  o << "},\n  \"insert\": {\"nodes_created\": " << st.insert.nodesCreated << ", \"leaves_created\": "
    << st.insert.leavesCreated << ", \"culled_nodes\": " << st.insert.culledNodes << ", \"culled_leaves\": "
    << st.insert.culledLeaves << "},\n  \"levels\": [";
  for (int l = -1; l < int(dag.levels.size()); ++l) {
    size_t n = l < 0 ? dag.leaves.size() : dag.levels[l].size();
    o << (l < 0 ? "\n    " : ",\n    ") << "{\"size\": " << (l < 0 ? 1 : (1u << (l + 3))) << ", \"nodes\": " << n
      << ", \"bytes\": " << dag.levelBytes(l) << "}";
  }
  o << "\n  ],\n  \"out\": " << jsonString(a.out) << "\n}\n";
  return o.str();
}

void printSummary(const BakeArgs& a, const Scene& scene, const SceneStats& ss, const CpvsArtifact& art,
                  const StageTimes& st, double total, uint64_t tiles, uint64_t fileBytes) {
  const Dag& dag = art.dag;
  uint64_t R = art.grid.resolution();
  std::printf("\nBaked %s (%zu triangles, %zu closed) at %llu^3 in %llu tile%s\n", scene.name.c_str(), ss.triangles,
              ss.closedTriangles, static_cast<unsigned long long>(R), static_cast<unsigned long long>(tiles),
              tiles == 1 ? "" : "s");
  std::printf("  options: closed=%s exit=%s cull=%s compress=%s undefined=%s renderer=%s tile=%u\n",
              optionName(art.options.closed), optionName(art.options.exit), art.options.cull ? "on" : "off",
              optionName(art.options.compress), optionName(art.options.undefinedRule), optionName(art.options.renderer),
              1u << art.options.log2TileSize);
  std::printf("  receivers: %s\n", receiversText(art.options, art.receiverHash).c_str());
  std::printf("  tiles not rendered (no triangle, or no receiver's reads): %llu of %llu\n",
              static_cast<unsigned long long>(st.tilesSkipped), static_cast<unsigned long long>(tiles));
  if (!a.tileCache.empty())
    std::printf("  tiles taken from the tile cache %s: %llu of %llu\n", a.tileCache.c_str(),
                static_cast<unsigned long long>(st.tilesReused), static_cast<unsigned long long>(tiles));
  std::printf("\n  %-11s %10s\n", "stage", "seconds");
  for (const char* name : kStageNames)
    if (auto it = st.seconds.find(name); it != st.seconds.end()) std::printf("  %-11s %10.3f\n", name, it->second);
  std::printf("  %-11s %10.3f\n", "total", total);
  std::printf("\n  %-10s %12s %12s\n", "node size", "nodes", "bytes");
  for (int l = -1; l < int(dag.levels.size()); ++l) {
    size_t n = l < 0 ? dag.leaves.size() : dag.levels[l].size();
    std::string size = l < 0 ? "leaf 8x8x1" : std::to_string(1u << (l + 3)) + "^3";
    std::printf("  %-10s %12zu %12llu\n", size.c_str(), n, static_cast<unsigned long long>(dag.levelBytes(l)));
  }
  uint64_t sm = R * R * 2;
  std::printf("\n  DAG: %s (%llu bytes), file: %s\n", humanBytes(dag.bytes()).c_str(),
              static_cast<unsigned long long>(dag.bytes()), humanBytes(fileBytes).c_str());
  std::printf("  16-bit shadow map of %llu^2: %s, %.1fx larger than the DAG\n", static_cast<unsigned long long>(R),
              humanBytes(sm).c_str(), double(sm) / double(std::max<uint64_t>(1, dag.bytes())));
  std::printf("  insertion: %llu nodes and %llu leaves created, %llu nodes and %llu leaves reused (culled)\n",
              static_cast<unsigned long long>(st.insert.nodesCreated),
              static_cast<unsigned long long>(st.insert.leavesCreated),
              static_cast<unsigned long long>(st.insert.culledNodes),
              static_cast<unsigned long long>(st.insert.culledLeaves));
  std::printf("\nWrote %s\n", a.out.c_str());
  std::printf("Look at it: cpvs render %s %s --out %s.png\n", a.out.c_str(), a.scene.c_str(),
              a.out.substr(0, a.out.size() - (a.out.size() > 5 && a.out.ends_with(".cpvs") ? 5 : 0)).c_str());
}

// `--spot`, `--point`, `--lights`: a light bundle.
int runLightBake(const BakeArgs& a, const std::chrono::steady_clock::time_point totalStart) {
  if (!a.tileCache.empty()) throw InputError("--tile-cache keeps a sun bake's tiles: a light bundle bakes every tile");
  checkNoSunWithLights(a.sun);
  if (!a.options.media.empty()) throw InputError("--medium: media are read through a sun's grid, not a light bundle's");
  const BakeOptions opt = optionsOf(a.options);
  const ReceiverDeclaration receivers = receiversOf(a.options);
  if (a.pointerGrid < 0 || a.pointerGrid > kMaxGridLevels)
    throw InputError("--pointer-grid " + std::to_string(a.pointerGrid) + ": levels 0 to " + std::to_string(kMaxGridLevels));
  std::vector<Light> given = flagLights(a.lights);
  StageTimes st;
  auto start = std::chrono::steady_clock::now();
  SceneStats ss;
  Scene scene = openScene(a.scene, &ss);
  const std::vector<Light> lights = withSceneLights(a.lights, std::move(given), scene, a.scene);
  checkLightCount(lights.size());
  const double footprint = footprintOf(a.lights, scene);
  st.add("load", secondsSince(start));
  if (!a.json && !a.quiet)
    spdlog::info("{}: {} triangles ({} closed), {} light{}, texels at most {:.4g} wide at a light's far end", scene.name,
                 ss.triangles, ss.closedTriangles, lights.size(), lights.size() == 1 ? "" : "s", footprint);
  ProgressDisplay progress(!a.json && !a.quiet);
  LightBundle bundle = bakeLights(
      scene, lights, footprint, opt, sceneHash(scene), &st,
      [&](const Progress& p) { return progress.update(p); }, nullptr, receivers);
  progress.finish();
  if (a.pointerGrid != kMaxGridLevels) bundle = withPointerGrids(bundle, a.pointerGrid);
  start = std::chrono::steady_clock::now();
  const std::vector<uint8_t> bytes = encodeBundle(bundle, a.zstd);
  writeFileAtomic(a.out, bytes);
  st.add("write", secondsSince(start));
  const double total = secondsSince(totalStart);
  if (a.json) {
    std::cout << "{\n  \"scene\": " << jsonString(scene.name) << ",\n  \"scene_hash\": " << jsonString(bundle.sceneHash.hex())
              << ",\n  \"triangles\": " << ss.triangles << ",\n  \"footprint\": " << jsonNumber(footprint) << ",\n  "
              << bundleJsonFields(bundle) << ",\n  \"file_bytes\": " << bytes.size()
              << ",\n  \"seconds_total\": " << jsonNumber(total) << ",\n  \"out\": " << jsonString(a.out) << "\n}\n";
    return 0;
  }
  std::printf("\nBaked %zu light%s of %s (%zu triangles) in %.2f s, renderer %s\n\n%s", bundle.lights.size(),
              bundle.lights.size() == 1 ? "" : "s", scene.name.c_str(), ss.triangles, total,
              optionName(opt.renderer), bundleTable(bundle).c_str());
  std::printf("  file: %s\n\nWrote %s\n", humanBytes(bytes.size()).c_str(), a.out.c_str());
  std::printf("Look at it: cpvs inspect %s\n", a.out.c_str());
  return 0;
}

// `--format dagmh`: the sun's shadows as a DAG-MH (seed 001).
int runDagMhBake(const BakeArgs& a, const std::chrono::steady_clock::time_point totalStart) {
  if (a.lights.given()) throw InputError("--format dagmh bakes the sun: local lights bake into a light bundle (--format cpvs)");
  if (!a.tileCache.empty()) throw InputError("--tile-cache keeps a CPVS bake's tiles, not a DAG-MH's");
  if (a.options.depthSlices != 0) throw InputError("--depth-slices: a DAG-MH stores float depths on a cubic grid");
  if (!a.options.media.empty()) throw InputError("--medium is read through a CPVS, not a DAG-MH");
  if (a.pointerGrid != kMaxGridLevels) throw InputError("--pointer-grid is for light bundles (--spot, --point, --lights)");
  const BakeOptions opt = optionsOf(a.options);
  const ReceiverDeclaration receivers = receiversOf(a.options);
  const int log2R = parseResolution(a.resolution);
  if (log2R > kMaxLog2DagMhResolution)
    throw InputError("--resolution " + a.resolution + ": a DAG-MH is baked up to " +
                     std::to_string(1u << kMaxLog2DagMhResolution) + " texels a side");
  const LightFrame frame = lightFromFlags(a.sun.dir, a.sun.elevation, a.sun.azimuth);
  StageTimes st;
  auto start = std::chrono::steady_clock::now();
  SceneStats ss;
  const Scene scene = openScene(a.scene, &ss);
  DmhArtifact art;
  art.grid = makeGrid(scene, frame, log2R);
  art.options = opt;
  art.sceneHash = sceneHash(scene);
  art.receiverHash = receiverHash(receivers);
  st.add("load", secondsSince(start));
  if (!a.json && !a.quiet)
    spdlog::info("{}: {} triangles ({} closed), a DAG-MH of {}^2 texels for receivers {}, light ({:.4f}, {:.4f}, {:.4f})",
                 scene.name, ss.triangles, ss.closedTriangles, art.grid.resolution(), optionName(opt.receivers),
                 frame.dir.x, frame.dir.y, frame.dir.z);
  ProgressDisplay progress(!a.json && !a.quiet);
  art.dag = bakeDagMh(scene, art.grid, opt, receivers, a.threads, &st, [&](const Progress& p) { return progress.update(p); });
  progress.finish();
  start = std::chrono::steady_clock::now();
  const std::vector<uint8_t> bytes = encodeDmh(art, a.zstd);
  writeFileAtomic(a.out, bytes);
  st.add("write", secondsSince(start));
  const double total = secondsSince(totalStart);
  if (a.json) {
    std::cout << "{\n  \"scene\": " << jsonString(scene.name) << ",\n  \"scene_hash\": " << jsonString(art.sceneHash.hex())
              << ",\n  \"triangles\": " << ss.triangles << ",\n  " << dagMhJsonFields(art) << ",\n  \"file_bytes\": "
              << bytes.size() << ",\n  \"seconds_total\": " << jsonNumber(total) << ",\n  \"stages\": {";
    bool first = true;
    for (const auto& [k, v] : st.seconds) {
      std::cout << (first ? "" : ", ") << jsonString(k) << ": " << jsonNumber(v);
      first = false;
    }
    std::cout << "},\n  \"out\": " << jsonString(a.out) << "\n}\n";
    return 0;
  }
  std::printf("\nBaked %s (%zu triangles, %zu closed) as a DAG-MH of %llu^2 texels in %.2f s\n", scene.name.c_str(),
              ss.triangles, ss.closedTriangles, static_cast<unsigned long long>(art.grid.resolution()), total);
  std::printf("  receivers: %s\n\n  %-11s %10s\n", receiversText(opt, art.receiverHash).c_str(), "stage", "seconds");
  for (const char* name : {"load", "cameras", "render", "receivers", "hierarchy", "compress", "write"})
    if (auto it = st.seconds.find(name); it != st.seconds.end()) std::printf("  %-11s %10.3f\n", name, it->second);
  std::printf("  %-11s %10.3f\n\n%s  file: %s\n\nWrote %s\n", "total", total, dagMhTable(art.dag).c_str(),
              humanBytes(bytes.size()).c_str(), a.out.c_str());
  std::printf("Look at it: cpvs inspect %s\n", a.out.c_str());
  return 0;
}

int runBake(const BakeArgs& a) {
  auto totalStart = std::chrono::steady_clock::now();
  const auto limit = threadLimit(a.threads);
  checkOutputFolder(a.out, "--out");
  if (a.format == "dagmh") return runDagMhBake(a, totalStart);
  if (a.lights.given()) {
    if (a.options.depthSlices != 0) throw InputError("--depth-slices is the sun's: a light's grids are cubic");
    return runLightBake(a, totalStart);
  }
  if (a.pointerGrid != kMaxGridLevels) throw InputError("--pointer-grid is for light bundles (--spot, --point, --lights)");

  const BakeOptions opt = optionsOf(a.options);
  int log2R = parseResolution(a.resolution);
  checkDepthSlices(a.options.depthSlices, log2R, "--depth-slices");
  const LightFrame frame = lightFromFlags(a.sun.dir, a.sun.elevation, a.sun.azimuth);

  StageTimes st;
  auto start = std::chrono::steady_clock::now();
  SceneStats ss;
  Scene scene = openScene(a.scene, &ss);
  OrthoGrid grid = makeGrid(scene, frame, log2R, a.options.depthSlices);
  const ReceiverDeclaration receivers = receiversOf(a.options);
  st.add("load", secondsSince(start));
  if (receivers.kind == ReceiverKind::Cameras && receivers.cameraVisibility == CameraVisibility::Sampled) {
    // Cast once here (the declaration keeps the sides), timed as a stage of its own.
    start = std::chrono::steady_clock::now();
    if (!a.json && !a.quiet)
      spdlog::info("cameras: casting rays from {} positions to find the sides they see", cameraPositionCount(receivers));
    (void)receivingSides(scene, receivers);
    st.add("cameras", secondsSince(start));
  }
  start = std::chrono::steady_clock::now();
  BakeScene prepared(scene, grid, opt.renderer, a.threads, receivers);
  st.add("load", secondsSince(start));
  if (!a.json && !a.quiet)
    spdlog::info("{}: {} triangles ({} closed, {} degenerate dropped), resolution {}^2 x {} slices, light ({:.4f}, "
                 "{:.4f}, {:.4f})",
                 scene.name, ss.triangles, ss.closedTriangles, ss.degenerateDropped, grid.resolution(),
                 grid.depthSlices != 0 ? uint64_t(grid.depthSlices) : grid.resolution(), frame.dir.x, frame.dir.y,
                 frame.dir.z);

  ProgressDisplay progress(!a.json && !a.quiet);
  CpvsArtifact art;
  art.grid = grid;
  art.options = opt;
  art.sceneHash = sceneHash(scene);
  art.receiverHash = receiverHash(receivers);
  // The plan, stored in the file, reads the prepared scene only: made while tiles bake.
  // Its inputs are checked here, and the string it fills outlives the group, which waits
  // for it on every way out.
  std::string plan;
  const auto media = declaredMedia(a.options);
  tbb::task_group planning;
  planning.run([&] {
    plan = planJson(planBake(scene, ss, opt, receivers, prepared.raster(), prepared.receivers(), media));
  });
  std::optional<TileCache> cache;
  if (!a.tileCache.empty()) {
    cache.emplace(a.tileCache, a.tileCacheMb << 20);
    if (!tileKey(prepared, opt, 0, 0) && !a.quiet && !a.json)
      spdlog::warn("--tile-cache: tiles are kept for the raster renderer, receivers everywhere and compressed DAGs "
                   "only: this bake bakes every tile");
  }
  art.dag = bakeGrid(prepared, opt, &st, [&](const Progress& p) { return progress.update(p); }, cache ? &*cache : nullptr);
  progress.finish();
  planning.wait();
  art.plan = std::move(plan);
  if (hasTranslucentMeshes(scene)) {
    start = std::chrono::steady_clock::now();
    art.translucent = std::make_shared<const TopTree>(translucentTree(scene, PsvLight::sun(grid.frame.dir)));
    st.add("translucent", secondsSince(start));
  }

  start = std::chrono::steady_clock::now();
  auto bytes = encodeCpvs(art, a.zstd);
  writeFileAtomic(a.out, bytes);
  st.add("write", secondsSince(start));
  double total = secondsSince(totalStart);
  uint64_t tiles = TilePlan(log2R, opt.log2TileSize).perSide();
  tiles *= tiles;
  if (a.json)
    std::cout << summaryJson(a, scene, ss, art, st, total, tiles, bytes.size());
  else
    printSummary(a, scene, ss, art, st, total, tiles, bytes.size());
  return 0;
}

}  // namespace

void addBakeCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<BakeArgs>();
  CLI::App* c = app.add_subcommand(
      "bake", "Bake the sun shadows of a scene into a .cpvs file, or its local lights (--spot, --point, --lights) "
              "into a light bundle, in this process");
  c->add_option("scene", a->scene, "Scene file (glTF/GLB, OBJ, DAE, PLY, FBX, STL, ...), city[:BLOCKS[:SEED]] or landscape[:SIZE[:SEED]] (generated)")->required();
  c->add_option("--out,-o", a->out, "Output file: .cpvs (or a light bundle), .dmh with --format dagmh")->required();
  c->add_option("--format", a->format,
                "What to bake the sun into: cpvs (voxels, exact for every point --receivers declares) or dagmh (a "
                "DAG-encoded shadow map, seed 001: the same answers as the CPVS for the receivers declared, in fewer "
                "bytes; up to 64K)")
      ->check(CLI::IsMember({"cpvs", "dagmh"}))
      ->capture_default_str();
  addSunFlags(c, a->sun);
  c->add_option("--resolution,-r", a->resolution, "Grid resolution R (voxels a side): 1024, 4K, 16K, ... 1M")
      ->capture_default_str();
  addLightFlags(c, a->lights);
  c->add_option("--pointer-grid", a->pointerGrid,
                "Local lights: levels each grid's pointer grid answers in one read (seed 000 6.3), 0 (none) to 5 "
                "(32^3 cells, at most what the resolution allows); the same answers, another size and speed")
      ->capture_default_str();
  addOptionFlags(c, a->options, "Tile size in texels (power of two >= 8)");
  addThreadsFlag(c, a->threads);
  c->add_flag("!--no-zstd", a->zstd, "Store the levels uncompressed");
  c->add_option("--tile-cache", a->tileCache,
                "A folder of tiles' sub-DAGs kept under the content that decides them (the triangles reaching the "
                "tile, the grid, the options): a bake after an edit takes every tile the edit did not reach from "
                "here and bakes only the rest, the same bytes as a full bake (sun bakes with the raster renderer and "
                "receivers everywhere; other bakes bake every tile)");
  c->add_option("--tile-cache-mb", a->tileCacheMb, "What the tile cache may hold, least recently used out first")
      ->capture_default_str();
  c->add_flag("--json", a->json, "Print the summary as JSON on stdout");
  c->add_flag("--quiet,-q", a->quiet, "No progress output");
  c->callback([a, &status] { status = runBake(*a); });
}

}  // namespace cpvs::cli
