// `cpvs inspect`: what a .cpvs file holds, without the scene.
#include <cstdio>
#include <iostream>
#include <memory>
#include <sstream>

#include "bake_flags.h"
#include "bundle_text.h"
#include "cli_util.h"
#include "commands.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/io/dmh_file.h"
#include "dag_mh_text.h"

namespace cpvs::cli {

namespace {

struct InspectArgs {
  std::string file;
  bool json = false;
};

std::string levelLabel(int l) { return l < 0 ? "leaf 8x8x1" : std::to_string(1u << (l + 3)) + "^3"; }

std::string optionsText(const BakeOptions& o) {
  return "closed=" + std::string(optionName(o.closed)) + " exit=" + optionName(o.exit) + " cull=" + (o.cull ? "on" : "off") +
         " compress=" + optionName(o.compress) + " undefined=" + optionName(o.undefinedRule) + " renderer=" +
         optionName(o.renderer) + " tile=" + std::to_string(1u << o.log2TileSize);
}

int inspectBundle(const InspectArgs& a, const std::vector<uint8_t>& bytes) {
  const LightBundle b = decodeBundle(bytes.data(), bytes.size(), a.file);
  if (a.json) {
    std::cout << "{\n  \"file\": " << jsonString(a.file) << ",\n  \"format_version\": " << kBundleFormatVersion
              << ",\n  \"file_bytes\": " << bytes.size() << ",\n  \"scene_hash\": " << jsonString(b.sceneHash.hex())
              << ",\n  \"options\": {\"closed\": " << jsonString(optionName(b.options.closed))
              << ", \"exit\": " << jsonString(optionName(b.options.exit)) << ", \"cull\": " << (b.options.cull ? "true" : "false")
              << ", \"compress\": " << jsonString(optionName(b.options.compress))
              << ", \"undefined\": " << jsonString(optionName(b.options.undefinedRule))
              << ", \"renderer\": " << jsonString(optionName(b.options.renderer))
              << ", \"tile_size\": " << (1u << b.options.log2TileSize) << "},\n  \"plan\": " << (b.plan.empty() ? std::string("null") : b.plan) << ",\n  "
              << bundleJsonFields(b) << "\n}\n";
    return 0;
  }
  std::printf("%s: CPVS format %u (a light bundle), %s on disk\n", a.file.c_str(), kBundleFormatVersion,
              humanBytes(bytes.size()).c_str());
  std::printf("  scene hash   %s\n  options      %s\n\n%s", b.sceneHash.hex().c_str(), optionsText(b.options).c_str(),
              bundleTable(b).c_str());
  return 0;
}

// A DAG-MH: its header and its composition (seed 001's Tables 3 and 4).
int inspectDagMh(const InspectArgs& a, const std::vector<uint8_t>& bytes) {
  const DmhArtifact art = decodeDmh(bytes.data(), bytes.size(), a.file);
  const OrthoGrid& g = art.grid;
  if (a.json) {
    std::cout << "{\n  \"file\": " << jsonString(a.file) << ",\n  \"format_version\": " << kDmhFormatVersion
              << ",\n  \"file_bytes\": " << bytes.size() << ",\n  \"scene_hash\": " << jsonString(art.sceneHash.hex())
              << ",\n  \"light_dir\": [" << jsonNumber(g.frame.dir.x) << ", " << jsonNumber(g.frame.dir.y) << ", "
              << jsonNumber(g.frame.dir.z) << "],\n  \"receiver_declaration\": " << receiversJson(art.options, art.receiverHash)
              << ",\n  " << dagMhJsonFields(art) << "\n}\n";
    return 0;
  }
  std::printf("%s: DAG-MH format %u (a DAG-encoded shadow map, seed 001), %s on disk\n", a.file.c_str(), kDmhFormatVersion,
              humanBytes(bytes.size()).c_str());
  std::printf("  resolution   %llu^2 texels, depths in %llu slices (texel %.6g, slice %.6g world units)\n",
              static_cast<unsigned long long>(g.resolution()), static_cast<unsigned long long>(g.resolution()),
              g.texelSize(), g.sliceSize());
  std::printf("  light        (%.6f, %.6f, %.6f)\n", g.frame.dir.x, g.frame.dir.y, g.frame.dir.z);
  std::printf("  scene hash   %s\n", art.sceneHash.hex().c_str());
  std::printf("  options      closed=%s exit=%s\n", optionName(art.options.closed), optionName(art.options.exit));
  std::printf("  receivers    %s\n", receiversText(art.options, art.receiverHash).c_str());
  std::printf("  structure    treelets of 4 levels, skip list at level %d; values in chunks of %u\n\n%s",
              art.dag.skipLevel, kValuesPerChunk, dagMhTable(art.dag).c_str());
  return 0;
}

int runInspect(const InspectArgs& a) {
  auto bytes = readFile(a.file);
  if (isDmh(bytes.data(), bytes.size())) return inspectDagMh(a, bytes);
  if (cpvsFormatVersion(bytes.data(), bytes.size(), a.file) == kBundleFormatVersion) return inspectBundle(a, bytes);
  CpvsArtifact art = decodeCpvs(bytes.data(), bytes.size(), a.file);
  const Dag& dag = art.dag;
  // Bytes as they are walked and uploaded: an older file's layout is packed again as today's.
  auto levelBytes = [&](int l) { return dag.levelBytes(l); };
  // The bits of each level's references to its children (packed_layout.h): 16 where they fit.
  auto referenceBits = [&](int l) { return (art.packed.header().wideRefs >> l) & 1 ? 32 : 16; };
  const uint64_t dagBytes = art.packed.bytes();
  const OrthoGrid& g = art.grid;
  uint64_t R = g.resolution();
  const BakeOptions& o = art.options;
  if (a.json) {
    std::ostringstream s;
    s << "{\n  \"file\": " << jsonString(a.file) << ",\n  \"format_version\": " << art.formatVersion
      << ",\n  \"file_bytes\": " << bytes.size() << ",\n  \"resolution\": " << R << ",\n  \"scene_hash\": "
      << jsonString(art.sceneHash.hex()) << ",\n  \"light_dir\": [" << jsonNumber(g.frame.dir.x) << ", "
      << jsonNumber(g.frame.dir.y) << ", " << jsonNumber(g.frame.dir.z) << "],\n  \"grid\": {\"origin\": ["
      << jsonNumber(g.origin.x) << ", " << jsonNumber(g.origin.y) << ", " << jsonNumber(g.origin.z)
      << "], \"u0\": " << jsonNumber(g.u0) << ", \"v0\": " << jsonNumber(g.v0) << ", \"d0\": " << jsonNumber(g.d0)
      << ", \"extent\": " << jsonNumber(g.extent) << ", \"depth_extent\": " << jsonNumber(g.depthExtent)
      << ", \"depth_slices\": " << (g.depthSlices != 0 ? g.depthSlices : R) << "},\n  \"options\": {\"closed\": " << jsonString(optionName(o.closed))
      << ", \"exit\": " << jsonString(optionName(o.exit)) << ", \"cull\": " << (o.cull ? "true" : "false")
      << ", \"compress\": " << jsonString(optionName(o.compress))
      << ", \"undefined\": " << jsonString(optionName(o.undefinedRule))
      << ", \"renderer\": " << jsonString(optionName(o.renderer)) << ", \"tile_size\": " << (1u << o.log2TileSize)
      << "},\n  \"receivers\": " << receiversJson(o, art.receiverHash)
      << ",\n  \"plan\": " << (art.plan.empty() ? std::string("null") : art.plan)
      << ",\n  \"bytes\": " << dagBytes << ",\n  \"nodes\": " << dag.nodeCount()
      << ",\n  \"shadow_map_bytes\": " << R * R * 2;
    if (const TopTree* t = art.translucent.get())
      s << ",\n  \"translucent\": {\"frusta\": " << t->frustumCount() << ", \"bytes\": " << t->bytes() + 12 * t->frustumCount() << "}";
    s << ",\n  \"levels\": [";
    for (int l = -1; l < int(dag.levels.size()); ++l) {
      size_t n = l < 0 ? dag.leaves.size() : dag.levels[l].size();
      s << (l < 0 ? "\n    " : ",\n    ") << "{\"size\": " << (l < 0 ? 1 : (1u << (l + 3))) << ", \"nodes\": " << n
        << ", \"bytes\": " << levelBytes(l);
      if (l >= 0) s << ", \"reference_bits\": " << referenceBits(l);
      s << "}";
    }
    s << "\n  ]\n}\n";
    std::cout << s.str();
    return 0;
  }
  std::printf("%s: CPVS format %u, %s on disk\n", a.file.c_str(), art.formatVersion, humanBytes(bytes.size()).c_str());
  if (g.depthSlices == 0)
    std::printf("  resolution   %llu^3 (texel %.6g, slice %.6g world units)\n", static_cast<unsigned long long>(R),
                g.texelSize(), g.sliceSize());
  else
    std::printf("  resolution   %llu^2 x %u depth slices over the scene, a %llu^3 DAG whose slices behind it repeat "
                "its last (texel %.6g, slice %.6g world units)\n",
                static_cast<unsigned long long>(R), g.depthSlices, static_cast<unsigned long long>(R), g.texelSize(),
                g.sliceSize());
  std::printf("  light        (%.6f, %.6f, %.6f)\n", g.frame.dir.x, g.frame.dir.y, g.frame.dir.z);
  std::printf("  grid origin  (%.6g, %.6g, %.6g), extent %.6g, depth %.6g\n", g.origin.x, g.origin.y, g.origin.z,
              g.extent, g.depthExtent);
  std::printf("  scene hash   %s\n", art.sceneHash.hex().c_str());
  std::printf("  options      %s\n", optionsText(o).c_str());
  std::printf("  receivers    %s\n", receiversText(o, art.receiverHash).c_str());
  std::printf("  plan         %s\n", art.plan.empty() ? "none recorded (a file before format 3)" : loggable(art.plan, 4000).c_str());
  std::printf("\n  %-10s %12s %12s %12s\n", "node size", "nodes", "bytes", "references");
  for (int l = -1; l < int(dag.levels.size()); ++l) {
    size_t n = l < 0 ? dag.leaves.size() : dag.levels[l].size();
    const std::string refs = l < 0 ? "" : std::to_string(referenceBits(l)) + "-bit";
    std::printf("  %-10s %12zu %12llu %12s\n", levelLabel(l).c_str(), n, static_cast<unsigned long long>(levelBytes(l)),
                refs.c_str());
  }
  uint64_t sm = R * R * 2;
  std::printf("  %-10s %12zu %12llu\n", "total", dag.nodeCount(), static_cast<unsigned long long>(dagBytes));
  std::printf("\n  DAG %s; a 16-bit shadow map of %llu^2 is %s (%.1fx)\n", humanBytes(dagBytes).c_str(),
              static_cast<unsigned long long>(R), humanBytes(sm).c_str(),
              double(sm) / double(std::max<uint64_t>(1, dagBytes)));
  if (const TopTree* t = art.translucent.get())
    std::printf("  translucent casters: a TOP tree of %zu frusta beside the DAG, %s (nodes and transmittance); "
                "lookups multiply the light by it\n",
                t->frustumCount(), humanBytes(t->bytes() + 12 * t->frustumCount()).c_str());
  else
    std::printf("  translucent casters: none\n");
  return 0;
}

}  // namespace

void addInspectCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<InspectArgs>();
  CLI::App* c = app.add_subcommand(
      "inspect", "Show the header, options, and nodes and bytes per level of a .cpvs file, and its translucent "
                 "casters' tree (a light bundle: its lights with their bytes; a .dmh: its structure and values)");
  c->add_option("file", a->file, ".cpvs or .dmh file")->required();
  c->add_flag("--json", a->json, "Print as JSON");
  c->callback([a, &status] { status = runInspect(*a); });
}

}  // namespace cpvs::cli
