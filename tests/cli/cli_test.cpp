// The `cpvs` program as scripts use it: the JSON contract of bake, inspect and verify,
// queries, pictures, and clear errors with exit status 2 for bad input.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sys/wait.h>
#include <zlib.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "cpvs/io/cpvs_file.h"
#include "process_testing.h"
#include "scene_testing.h"
#include "cpvs/eval/image.h"

namespace cpvs {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using CliRun = testing::CommandResult;

/// Runs `cpvs ARGS` through the shell, bounded by coreutils' timeout.
CliRun cpvs(const std::string& args) { return testing::runShell("timeout 120 '" CPVS_CLI "' " + args + " 2>&1"); }

/// JSON printed on stdout (the commands print nothing else with --json and -q).
json parse(const CliRun& r) {
  size_t start = r.out.find('{');
  EXPECT_NE(start, std::string::npos) << r.out;
  return json::parse(r.out.substr(start == std::string::npos ? 0 : start));
}

class Cli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("cpvs_cli_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    CliRun r = cpvs("bake city:3 --sun-elevation 35 --sun-azimuth 20 -r 256 --tile-size 64 --json -o " + path("c.cpvs"));
    ASSERT_EQ(r.status, 0) << r.out;
    bake_ = parse(r);
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static std::string path(const std::string& name) { return (dir_ / name).string(); }

  static fs::path dir_;
  static json bake_;
};
fs::path Cli::dir_;
json Cli::bake_;

TEST_F(Cli, BakeJsonContract) {
  EXPECT_EQ(bake_["resolution"], 256);
  EXPECT_EQ(bake_["shadow_map_bytes"], 256 * 256 * 2);
  EXPECT_GT(bake_["bytes"].get<uint64_t>(), 0u);
  EXPECT_GE(bake_["seconds_total"].get<double>(), 0.0);
  EXPECT_EQ(bake_["tiles"], 16);
  for (const char* stage : {"render", "masks", "insert", "compress", "merge", "write"})
    EXPECT_TRUE(bake_["stages"].contains(stage)) << stage;
  // The summary's bytes are the DAG in the file.
  CpvsArtifact a = readCpvs(path("c.cpvs"));
  EXPECT_EQ(bake_["bytes"].get<uint64_t>(), a.dag.bytes());
  EXPECT_EQ(a.grid.resolution(), 256u);
  EXPECT_EQ(a.options.log2TileSize, 6);
  EXPECT_EQ(a.options.renderer, Renderer::Raster);
  EXPECT_EQ(bake_["options"]["renderer"], "raster");
}

// --renderer embree bakes with the ray tracer and says so in the file and the summary; the
// voxels agree with the rasterizer's everywhere but on a handful of grazing texels.
TEST_F(Cli, RendererChoiceIsRecorded) {
  CliRun r = cpvs("bake city:3 --sun-elevation 35 --sun-azimuth 20 -r 256 --tile-size 64 --renderer embree --json -o " +
                  path("e.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(parse(r)["options"]["renderer"], "embree");
  CliRun i = cpvs("inspect --json " + path("e.cpvs"));
  ASSERT_EQ(i.status, 0) << i.out;
  EXPECT_EQ(parse(i)["options"]["renderer"], "embree");
  CliRun bad = cpvs("bake city:3 --sun-dir 0,-1,0 -r 256 --renderer gpu -o " + path("g.cpvs"));
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.out.find("--renderer"), std::string::npos) << bad.out;
}

TEST_F(Cli, InspectJsonContract) {
  CliRun r = cpvs("inspect --json " + path("c.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  json j = parse(r);
  EXPECT_EQ(j["resolution"], 256);
  EXPECT_EQ(j["bytes"], bake_["bytes"]);
  ASSERT_TRUE(j["levels"].is_array());
  uint64_t sum = 0;
  for (const auto& l : j["levels"]) {
    EXPECT_TRUE(l.contains("nodes"));
    sum += l["bytes"].get<uint64_t>();
  }
  EXPECT_EQ(sum, j["bytes"].get<uint64_t>());
  EXPECT_EQ(j["levels"].size(), 1u + 6u);  // leaves and node sizes 8 .. 256
  EXPECT_EQ(j["levels"].back()["nodes"], 1);
}

TEST_F(Cli, InspectTextNamesTheLevels) {
  CliRun r = cpvs("inspect " + path("c.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("256^3"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("compress=topdown"), std::string::npos) << r.out;
}

// --format dagmh: a .dmh for the receivers declared, its composition, its verification.
TEST_F(Cli, DagMhBakesInspectsAndVerifies) {
  const std::string sun = " --sun-elevation 35 --sun-azimuth 20 -r 256 ";
  CliRun r = cpvs("bake city:3 --format dagmh --receivers surfaces" + sun + "--json -o " + path("d.dmh"));
  ASSERT_EQ(r.status, 0) << r.out;
  const json b = parse(r);
  EXPECT_EQ(b["format"], "dagmh");
  EXPECT_EQ(b["receivers"], "surfaces");
  EXPECT_EQ(b["bytes"].get<uint64_t>(), b["inner_node_bytes"].get<uint64_t>() + b["treelet_bytes"].get<uint64_t>() +
                                            b["chunk_map_bytes"].get<uint64_t>() + b["factor_bytes"].get<uint64_t>() +
                                            b["skip_bytes"].get<uint64_t>());
  for (const char* stage : {"render", "receivers", "hierarchy", "compress", "write"})
    EXPECT_TRUE(b["stages"].contains(stage)) << stage;
  CliRun i = cpvs("inspect --json " + path("d.dmh"));
  ASSERT_EQ(i.status, 0) << i.out;
  EXPECT_EQ(parse(i)["bytes"], b["bytes"]);
  EXPECT_EQ(parse(i)["receiver_declaration"]["kind"], "surfaces");
  CliRun t = cpvs("inspect " + path("d.dmh"));
  EXPECT_NE(t.out.find("DAG-MH format 1"), std::string::npos) << t.out;
  EXPECT_NE(t.out.find("treelets"), std::string::npos) << t.out;
  CliRun v = cpvs("verify --json -n 5000 " + path("d.dmh") + " city:3");
  ASSERT_EQ(v.status, 0) << v.out;
  EXPECT_EQ(parse(v)["mismatch_elsewhere_count"], 0);
  EXPECT_GT(parse(v)["samples"].get<uint64_t>(), 4000u);
  // What a DAG-MH does not take, said by name.
  for (const auto& [flags, words] : std::vector<std::pair<std::string, std::string>>{
           {"--depth-slices 64", "--depth-slices"},
           {"--tile-cache " + path("cache"), "--tile-cache"},
           {"--spot 0,10,0:0,-1,0:40", "light bundle"},
           {"--format png", "--format"}}) {
    CliRun bad = cpvs("bake city:3 --format dagmh " + flags + sun + "-o " + path("bad.dmh"));
    EXPECT_NE(bad.status, 0) << flags;
    EXPECT_NE(bad.out.find(words), std::string::npos) << flags << ": " << bad.out;
  }
  // Looked up on the runtime's device (lavapipe here): the CPU's answers.
  std::ofstream csv(path("d.csv"));
  csv << "x,y,z,nx,ny,nz\n";
  for (int i = 0; i < 400; ++i) csv << (i * 7) % 90 << "," << (i % 13) * 3 - 5 << "," << (i * 11) % 90 << ",0,1,0\n";
  csv.close();
  CliRun cpuCsv = cpvs("query " + path("d.dmh") + " --points " + path("d.csv") + " --pcf 3");
  CliRun gpuCsv = cpvs("query " + path("d.dmh") + " --points " + path("d.csv") + " --pcf 3 --gpu");
  ASSERT_EQ(cpuCsv.status, 0) << cpuCsv.out;
  ASSERT_EQ(gpuCsv.status, 0) << gpuCsv.out;
  EXPECT_NE(gpuCsv.out.find("Vulkan"), std::string::npos) << gpuCsv.out;
  const std::string header = "x,y,z,visibility";
  ASSERT_NE(gpuCsv.out.find(header), std::string::npos);
  ASSERT_NE(cpuCsv.out.find(header), std::string::npos);
  EXPECT_EQ(cpuCsv.out.substr(cpuCsv.out.find(header)), gpuCsv.out.substr(gpuCsv.out.find(header)));  // after the notes
  EXPECT_NE(cpuCsv.out.find(",0\n"), std::string::npos) << "some points in shadow";
  // And drawn there: the same picture, to the byte.
  for (const std::string& gpu : {"", " --gpu"}) {
    CliRun r = cpvs("render " + path("d.dmh") + " city:3 --size 160x120 --pcf 3" + gpu + " -o " +
                    path(gpu.empty() ? "d-cpu.png" : "d-gpu.png"));
    ASSERT_EQ(r.status, 0) << r.out;
    EXPECT_NE(r.out.find(gpu.empty() ? "the CPU" : "Vulkan"), std::string::npos) << r.out;
  }
  std::ifstream x(path("d-cpu.png"), std::ios::binary), y(path("d-gpu.png"), std::ios::binary);
  const std::string cpuPng((std::istreambuf_iterator<char>(x)), {}), gpuPng((std::istreambuf_iterator<char>(y)), {});
  EXPECT_GT(cpuPng.size(), 1000u);
  EXPECT_EQ(cpuPng, gpuPng);
  CliRun big = cpvs("bake city:3 --format dagmh --sun-dir 0,-1,0 -r 128K -o " + path("big.dmh"));
  EXPECT_NE(big.status, 0);
  EXPECT_NE(big.out.find("65536"), std::string::npos) << big.out;
}

TEST_F(Cli, VerifyJsonContract) {
  CliRun r = cpvs("verify --json -n 5000 " + path("c.cpvs") + " city:3");
  ASSERT_EQ(r.status, 0) << r.out;
  json j = parse(r);
  EXPECT_GT(j["samples"].get<uint64_t>(), 4000u);
  EXPECT_EQ(j["mismatch_elsewhere"].get<double>(), 0.0);
  EXPECT_LT(j["mismatch_near_boundary"].get<double>(), 0.05);
  // The TOP tree is the second oracle by default; it alone, or Embree alone, on request.
  EXPECT_EQ(j["reference"], "both");
  EXPECT_EQ(j["oracles_compared"].get<uint64_t>(), j["samples"].get<uint64_t>());
  EXPECT_EQ(j["oracles_disagree_elsewhere_count"], 0);
  for (const char* reference : {"psv", "embree"}) {
    r = cpvs("verify --json -n 5000 --reference " + std::string(reference) + " " + path("c.cpvs") + " city:3");
    ASSERT_EQ(r.status, 0) << r.out;
    const json one = parse(r);
    EXPECT_EQ(one["reference"], reference);
    EXPECT_FALSE(one.contains("oracles_compared"));
    EXPECT_EQ(one["samples"], j["samples"]);
    EXPECT_EQ(one["mismatch_elsewhere_count"], 0);
    EXPECT_EQ(one["mismatch_near_boundary_count"], j["mismatch_near_boundary_count"]) << reference;
  }
  r = cpvs("verify -n 100 --reference rays " + path("c.cpvs") + " city:3");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.out.find("--reference"), std::string::npos) << r.out;
}

// A bake for declared receivers records them (bake and inspect show the same
// declaration), verify samples them and needs the volume given again, and an open level
// baked for its surfaces is smaller and exact on them.
TEST_F(Cli, ReceiversAreDeclaredInspectedAndVerified) {
  const std::string box = " --receiver-box -1000,0,-1000,1000,3,1000";
  CliRun r = cpvs("bake city:3 --sun-elevation 35 --sun-azimuth 20 -r 256 --tile-size 64 --json --receivers volume" +
                  box + " -o " + path("v.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  const json baked = parse(r)["receivers"];
  EXPECT_EQ(baked["kind"], "volume");
  EXPECT_EQ(baked["pcf"], 9);
  EXPECT_EQ(baked["hash"].get<std::string>().size(), 32u);
  EXPECT_EQ(bake_["receivers"]["kind"], "everywhere");
  EXPECT_TRUE(bake_["receivers"]["hash"].is_null());
  r = cpvs("inspect --json " + path("v.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(parse(r)["receivers"], baked);
  EXPECT_EQ(parse(r)["format_version"], 3);

  r = cpvs("verify -n 3000 " + path("v.cpvs") + " city:3");
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("baked for 'volume' receivers"), std::string::npos) << r.out;
  r = cpvs("verify -n 3000 " + path("v.cpvs") + " city:3 --receivers volume --receiver-box -1000,0,-1000,1000,4,1000");
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("not the one"), std::string::npos) << r.out;
  r = cpvs("verify --json -n 6000 " + path("v.cpvs") + " city:3 --receivers volume" + box);
  ASSERT_EQ(r.status, 0) << r.out;
  json v = parse(r);
  EXPECT_EQ(v["receivers"], "volume");
  EXPECT_GT(v["samples"].get<uint64_t>(), 3000u);
  EXPECT_EQ(v["mismatch_elsewhere_count"], 0);

  // A ground layer from 0.2 to 2 units over every walkable surface: verify samples it (and
  // wants it again), and it is larger than surfaces alone and smaller than everywhere.
  const std::string layer = " --receivers volume --ground-layer 0.2:2";
  r = cpvs("bake city:3 --sun-elevation 35 --sun-azimuth 20 -r 256 --tile-size 64 --json" + layer + " -o " + path("g.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  const uint64_t layerBytes = parse(r)["bytes"].get<uint64_t>();
  EXPECT_LT(layerBytes, bake_["bytes"].get<uint64_t>());
  r = cpvs("bake city:3 --sun-elevation 35 --sun-azimuth 20 -r 256 --tile-size 64 --json --receivers surfaces -o " +
           path("s.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_GT(layerBytes, parse(r)["bytes"].get<uint64_t>());
  r = cpvs("inspect --json " + path("g.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  const json ground = parse(r)["plan"]["receivers"]["ground_layer"];
  EXPECT_EQ(ground["from"], 0.2);
  EXPECT_EQ(ground["to"], 2);
  EXPECT_EQ(ground["slope_deg"], 45);
  EXPECT_GT(ground["walkable_triangles"].get<uint64_t>(), 0u);
  EXPECT_GT(ground["walkable_area_share"].get<double>(), 0.1);
  r = cpvs("verify -n 3000 " + path("g.cpvs") + " city:3 --receivers volume --ground-layer 2");
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("not the one"), std::string::npos) << r.out;
  r = cpvs("verify --json -n 6000 " + path("g.cpvs") + " city:3" + layer);
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_GT(parse(r)["samples"].get<uint64_t>(), 3000u);
  EXPECT_EQ(parse(r)["mismatch_elsewhere_count"], 0);

  // Cameras in a corner of the city seeing 40 units: verify wants the regions again.
  const std::string cams = " --receivers cameras --camera-region 0,1,0,20,3,20 --view-distance 40";
  r = cpvs("bake city:3 --sun-elevation 35 --sun-azimuth 20 -r 256 --tile-size 64 --json" + cams + " -o " + path("k.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(parse(r)["receivers"]["kind"], "cameras");
  EXPECT_LT(parse(r)["bytes"].get<uint64_t>(), bake_["bytes"].get<uint64_t>());  // the same bake for everywhere
  // The city's ground is one quad the corner sees, so every touched tile is read here (tiles no
  // receiver reads: in_process_farm_test, UntouchedTilesAreNotLeased...).
  EXPECT_GE(parse(r)["tiles_skipped"].get<uint64_t>(), bake_["tiles_skipped"].get<uint64_t>());
  r = cpvs("verify -n 3000 " + path("k.cpvs") + " city:3");
  EXPECT_EQ(r.status, 2) << r.out;
  r = cpvs("verify --json -n 6000 " + path("k.cpvs") + " city:3" + cams);
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(parse(r)["receivers"], "cameras");
  EXPECT_EQ(parse(r)["mismatch_elsewhere_count"], 0);

  // The same places in a camera file, plus a point and a path, seen by sampled rays:
  // occluders hide surfaces, so the bake is smaller still; verify reads the file again and
  // measures an independent sample.
  const std::string places =
      R"("cameraRegions": [{"min": {"x": 0, "y": 1, "z": 0}, "max": {"x": 20, "y": 3, "z": 20}}],
         "cameraPoints": [{"x": 30, "y": 2, "z": 5}],
         "cameraPaths": [{"points": [{"x": 0, "y": 1.5, "z": 25}, {"x": 25, "y": 1.5, "z": 25}]}], "viewDistance": 40)";
  std::ofstream(path("cams.json")) << "{" << places
                                   << R"(, "cameraVisibility": "CAMERA_VISIBILITY_SAMPLED", "cameraSpacing": 5, "cameraRays": 48})";
  std::ofstream(path("faced.json")) << "{" << places << "}";
  const std::string sampled = " --receivers cameras:" + path("cams.json");
  r = cpvs("bake city:3 --sun-elevation 35 --sun-azimuth 20 -r 256 --tile-size 64 --json" + sampled + " -o " + path("s.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  const uint64_t sampledBytes = parse(r)["bytes"].get<uint64_t>();
  // On one thread (the cast too: camera_views_test) the same bytes, and the same plan.
  r = cpvs("bake city:3 --sun-elevation 35 --sun-azimuth 20 -r 256 --tile-size 64 -q --threads 1" + sampled + " -o " +
           path("s1.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(readFile(path("s1.cpvs")), readFile(path("s.cpvs")));
  const std::string planOf =
      "plan city:3 --sun-elevation 35 --sun-azimuth 20 -r 256 --tile-size 64 --json --no-estimate" + sampled;
  r = cpvs(planOf + " --threads 1");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(r.out, cpvs(planOf).out);
  EXPECT_EQ(cpvs(planOf + " --threads -1").status, 2);
  r = cpvs("bake city:3 --sun-elevation 35 --sun-azimuth 20 -r 256 --tile-size 64 --json --receivers cameras:" +
           path("faced.json") + " -o " + path("f.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_LT(sampledBytes, parse(r)["bytes"].get<uint64_t>());
  r = cpvs("verify --json -n 6000 " + path("s.cpvs") + " city:3" + cams);
  EXPECT_EQ(r.status, 2) << r.out;  // the regions alone are another declaration
  r = cpvs("verify --json -n 6000 " + path("s.cpvs") + " city:3" + sampled);
  ASSERT_EQ(r.status, 0) << r.out;
  v = parse(r);
  EXPECT_EQ(v["mismatch_elsewhere_count"], 0);
  EXPECT_GT(v["independent_camera_sample"]["hits"].get<uint64_t>(), 10000u);
  EXPECT_LT(v["independent_camera_sample"]["hits_outside_share"].get<double>(), 0.05);
  // Camera files are checked: JSON, only camera fields, the declaration's rules.
  std::ofstream(path("bad1.json")) << R"({"cameraRegions": [)";
  std::ofstream(path("bad2.json")) << R"({"viewDistance": 40, "cameraPoints": [{"x": 1}], "maxPcf": 3})";
  std::ofstream(path("bad3.json")) << R"({"viewDistance": 40, "cameraPoints": [{"x": 1}], "cameraSpacing": 2})";
  for (const auto& [file, words] : std::vector<std::pair<std::string, std::string>>{
           {"bad1.json", "not a camera file"},
           {"bad2.json", "holds only cameraRegions"},
           {"bad3.json", "for sampled camera visibility only"},
           {"missing.json", "missing.json"}}) {
    r = cpvs("bake city:3 --sun-dir 0,-1,0 -r 256 --receivers cameras:" + path(file) + " -o " + path("x.cpvs"));
    EXPECT_EQ(r.status, 2) << file << ": " << r.out;
    EXPECT_NE(r.out.find(words), std::string::npos) << file << ": " << r.out;
  }
  r = cpvs("bake city:3 --sun-dir 0,-1,0 -r 256 --receivers surfaces --camera-visibility sampled -o " + path("x.cpvs"));
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("need --receivers cameras"), std::string::npos) << r.out;

  CPVS_SHARED_SCENE_OR_SKIP(town, "flightgear/zone_maisons.obj");
  uint64_t bytes[2] = {};
  int k = 0;
  for (const char* kind : {"everywhere", "surfaces"}) {
    const std::string out = path(std::string("town-") + kind + ".cpvs");
    r = cpvs("bake " + town + " --sun-elevation 40 --sun-azimuth 120 -r 1K --json --receivers " + kind + " -o " + out);
    ASSERT_EQ(r.status, 0) << r.out;
    bytes[k++] = parse(r)["bytes"].get<uint64_t>();
    r = cpvs("verify --json -n 20000 " + out + " " + town);
    ASSERT_EQ(r.status, 0) << r.out;
    v = parse(r);
    EXPECT_EQ(v["receivers"], kind);
    EXPECT_EQ(v["mismatch_elsewhere_count"], 0);
  }
  EXPECT_LT(bytes[1], bytes[0]);
}

// The plan: a glTF with a directional, a point and a spot light (KHR_lights_punctual) on
// an open triangle: the directional light is this bake's or named with its --sun-dir,
// the local lights are skipped with the reason, no exit search runs; a bake records the
// same plan, which inspect shows.
// The sun along a segment and through fog: the lit stretches and the medium's figures,
// and the refusals (a bake for surfaces leaves the air undefined; a medium needs a segment
// and sane coefficients).
TEST_F(Cli, SegmentsAndFogReadTheGridInTheAir) {
  CliRun r = cpvs("query " + path("c.cpvs") + " --segment 0,60,0:40,0,40");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("length 82.4621125  lit "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("lit from 0 to "), std::string::npos) << r.out;  // the sky above the city is lit
  r = cpvs("query " + path("c.cpvs") + " --segment 0,60,0:40,0,40 --medium 0.02,0.01,0.3");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("transmittance 0.0842"), std::string::npos) << r.out;  // e^(-0.03 * 82.46)
  EXPECT_NE(r.out.find("in-scattered "), std::string::npos) << r.out;
  r = cpvs("query " + path("c.cpvs") + " --segment 0,60,0:40,0,40 --medium 0.02,-1");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.out.find("absorption"), std::string::npos) << r.out;
  r = cpvs("query " + path("c.cpvs") + " --point 1,2,3 --medium 0.02,0.01");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.out.find("--medium goes with --segment"), std::string::npos) << r.out;
  r = cpvs("query " + path("c.cpvs") + " --segment 0,60,0");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.out.find("AX,AY,AZ:BX,BY,BZ"), std::string::npos) << r.out;
  r = cpvs("render " + path("c.cpvs") + " city:3 --size 64x40 --fog 0.02,0.005,0.6 -o " + path("fog.png"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_GT(fs::file_size(path("fog.png")), 0u);
  // The fog walked on a device (lavapipe): the same picture but for float rounding.
  r = cpvs("render " + path("c.cpvs") + " city:3 --size 64x40 --gpu --fog 0.02,0.005,0.6 -o " + path("fog-gpu.png"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("sun shafts through the fog walked on llvmpipe"), std::string::npos) << r.out;
  const Image fogCpu = readPng(path("fog.png")), fogGpu = readPng(path("fog-gpu.png"));
  ASSERT_EQ(fogCpu.pixels.size(), fogGpu.pixels.size());
  double worst = 0;
  for (size_t i = 0; i < fogCpu.pixels.size(); ++i)
    worst = std::max({worst, double(std::abs(fogCpu.pixels[i].r - fogGpu.pixels[i].r)),
                      double(std::abs(fogCpu.pixels[i].b - fogGpu.pixels[i].b))});
  EXPECT_LE(worst, 0.01) << "one 8-bit step or so";
  // A medium declared with a bake: the plan offers light through it where the air is held.
  r = cpvs("plan city:3 --sun-dir 0.3,-1,0.2 -r 256 --json --medium 0.02,0.005,0.6");
  ASSERT_EQ(r.status, 0) << r.out;
  json plan = parse(r);
  ASSERT_EQ(plan["media"].size(), 1u) << r.out;
  EXPECT_EQ(plan["media"][0]["source"], "declared");
  EXPECT_EQ(plan["media"][0]["g"], 0.6);
  EXPECT_TRUE(plan["media"][0]["offered"].get<bool>());
  r = cpvs("plan city:3 --sun-dir 0.3,-1,0.2 -r 256 --json --medium 0.02,0.005 --receivers surfaces");
  ASSERT_EQ(r.status, 0) << r.out;
  plan = parse(r);
  EXPECT_FALSE(plan["media"][0]["offered"].get<bool>());
  EXPECT_NE(plan["media"][0]["reason"].get<std::string>().find("leave the air undefined"), std::string::npos);
  r = cpvs("plan city:3 --sun-dir 0.3,-1,0.2 -r 256 --tile-size 32 --json");
  ASSERT_EQ(r.status, 0) << r.out;
  plan = parse(r);
  EXPECT_TRUE(plan["media"].empty()) << "no medium declared, none offered";
  // Beside the plan, its cost: some of the bake's own tiles baked to price the rest.
  EXPECT_EQ(plan["estimate"]["tiles"], 64);
  EXPECT_GE(plan["estimate"]["sampled_tiles"].get<int>(), 3) << r.out;
  EXPECT_GT(plan["estimate"]["tile_seconds"].get<double>(), 0);
  EXPECT_GT(plan["estimate"]["dag_bytes"].get<uint64_t>(), 0u);
  r = cpvs("plan city:3 --sun-dir 0.3,-1,0.2 -r 256");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("cost, measured ("), std::string::npos) << r.out;
  EXPECT_EQ(cpvs("plan city:3 --sun-dir 0.3,-1,0.2 -r 256 --no-estimate").out.find("cost, measured"), std::string::npos);
  // An output that names a folder is refused before any work.
  r = cpvs("bake city:3 --sun-dir 0.3,-1,0.2 -r 64 -o " + path(""));
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("is a folder"), std::string::npos) << r.out;
  r = cpvs("bake city:3 --sun-dir 0.3,-1,0.2 -r 64 -q --medium 0.02,0.005 -o " + path("fog.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  r = cpvs("inspect --json " + path("fog.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("medium 1"), std::string::npos) << "the artifact records the declared medium: " << r.out;
  r = cpvs("bake city:3 --sun-dir 0.3,-1,0.2 -r 64 -q --receivers surfaces -o " + path("air.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  for (const std::string& command : {"query " + path("air.cpvs") + " --segment 0,60,0:40,0,40",
                                     "render " + path("air.cpvs") + " city:3 --size 64x40 --fog 0.02,0 -o " + path("x.png")}) {
    r = cpvs(command);
    EXPECT_NE(r.status, 0) << command;
    EXPECT_NE(r.out.find("undefined in the air"), std::string::npos) << r.out;
  }
}

// An area light from the command line: its VPLs in the bundle (inspect names them), its
// soft visibility (`query --soft`): lit in the open under it, 0 behind it; the refusals.
TEST_F(Cli, AreaLightsAreBakedAsVplsAndAnswerSoftly) {
  CliRun r = cpvs("bake city:3:5 --area-light 36,66,36:12,0,0:0,0,12:8:64 -q -o " + path("area.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  r = cpvs("inspect " + path("area.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("area 1 vpl 7"), std::string::npos) << r.out;
  r = cpvs("query " + path("area.cpvs") + " --soft --point 36,60,36 --normal 0,-1,0");  // facing away: none
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("area light 1 (8 VPLs)  soft visibility 0.0000"), std::string::npos) << r.out;
  r = cpvs("query " + path("area.cpvs") + " --soft --point 36,64,36 --normal 0,1,0");  // just under it, facing it
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("soft visibility 1.0000"), std::string::npos) << r.out;
  // Each VPL's grids checked as a point light's against exact rays: no mismatch away from
  // a shadow boundary (verify's exit status).
  r = cpvs("verify " + path("area.cpvs") + " city:3:5 -n 20000");
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("area 1 vpl 7"), std::string::npos) << r.out;
  // The picture shades with soft visibility; on a device (lavapipe) the same to the bit.
  r = cpvs("render " + path("area.cpvs") + " city:3:5 --size 96x64 -o " + path("soft-cpu"));
  ASSERT_EQ(r.status, 0) << r.out;
  r = cpvs("render " + path("area.cpvs") + " city:3:5 --size 96x64 --gpu -o " + path("soft-gpu"));
  ASSERT_EQ(r.status, 0) << r.out;
  const auto bytesOf = [](const std::string& f) {
    std::ifstream in(f, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  EXPECT_GT(bytesOf(path("soft-cpu.exr")).size(), 1000u);
  EXPECT_EQ(bytesOf(path("soft-cpu.exr")), bytesOf(path("soft-gpu.exr")));
  for (const auto& [args, says] :
       {std::pair{"bake city:3:5 --area-light 36,66,36:12,0,0:24,0,0 -o " + path("bad.cpvs"), std::string("no area")},
        std::pair{"bake city:3:5 --area-light 36,66,36:12,0,0:0,0,12:0 -o " + path("bad.cpvs"), std::string("VPL count")},
        std::pair{"query " + path("c.cpvs") + " --soft --point 1,2,3", std::string("has the sun only")},
        std::pair{"query " + path("area.cpvs") + " --soft --pcf 3 --point 1,2,3", std::string("no --light or --pcf")}}) {
    r = cpvs(args);
    EXPECT_NE(r.status, 0) << args;
    EXPECT_NE(r.out.find(says), std::string::npos) << args << ": " << r.out;
  }
}

TEST_F(Cli, PlanSaysWhatABakeComputesAndTheBakeRecordsIt) {
  std::ofstream(path("lights.gltf")) << "{\"asset\": {\"version\": \"2.0\"}, \"extensionsUsed\": [\"KHR_lights_punctual\"], \"extensions\": {\"KHR_lights_punctual\": {\"lights\": [{\"type\": \"directional\", \"name\": \"sun\", \"color\": [1, 1, 1]}, {\"type\": \"point\", \"name\": \"lamp\"}, {\"type\": \"spot\", \"name\": \"torch\", \"spot\": {\"innerConeAngle\": 0.2, \"outerConeAngle\": 0.5}}]}}, \"scenes\": [{\"nodes\": [0, 1, 2, 3]}], \"scene\": 0, \"nodes\": [{\"mesh\": 0, \"name\": \"ground\"}, {\"name\": \"sunNode\", \"rotation\": [-0.7071068, 0, 0, 0.7071068], \"extensions\": {\"KHR_lights_punctual\": {\"light\": 0}}}, {\"name\": \"lampNode\", \"translation\": [1, 2, 3], \"extensions\": {\"KHR_lights_punctual\": {\"light\": 1}}}, {\"name\": \"torchNode\", \"translation\": [0, 5, 0], \"extensions\": {\"KHR_lights_punctual\": {\"light\": 2}}}], \"meshes\": [{\"primitives\": [{\"attributes\": {\"POSITION\": 0}}]}], \"buffers\": [{\"byteLength\": 36, \"uri\": \"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAAAAAAAAAAAAAIA/AACAPwAAAAAAAAAA\"}], \"bufferViews\": [{\"buffer\": 0, \"byteLength\": 36}], \"accessors\": [{\"bufferView\": 0, \"componentType\": 5126, \"count\": 3, \"type\": \"VEC3\", \"min\": [0, 0, 0], \"max\": [1, 0, 1]}]}";
  CliRun r = cpvs("plan " + path("lights.gltf") + " --sun-dir 0,-1,0 -r 1K --json --no-estimate");
  ASSERT_EQ(r.status, 0) << r.out;
  const json plan = parse(r);
  ASSERT_EQ(plan["lights"].size(), 3u);
  EXPECT_EQ(plan["lights"][0]["type"], "directional");
  EXPECT_EQ(plan["lights"][0]["baked"], true);
  EXPECT_EQ(plan["lights"][1]["type"], "point");
  EXPECT_EQ(plan["lights"][1]["baked"], false);
  EXPECT_NE(plan["lights"][1]["reason"].get<std::string>().find("--scene-lights"), std::string::npos);
  EXPECT_EQ(plan["lights"][2]["type"], "spot");
  EXPECT_EQ(plan["closed_parts"], 0);
  EXPECT_EQ(plan["passes"][1]["name"], "exit");
  EXPECT_EQ(plan["passes"][1]["runs"], false);
  EXPECT_TRUE(plan["media"].empty());
  r = cpvs("plan " + path("lights.gltf") + " --sun-dir 1,-1,0 -r 1K --json");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(parse(r)["lights"][0]["reason"].get<std::string>().find("--sun-dir 0,-1,0"), std::string::npos) << r.out;

  // Its lamp and torch stand far outside the one triangle: a bundle of them is refused.
  r = cpvs("bake " + path("lights.gltf") + " --scene-lights -o " + path("lights_bundle.cpvs"));
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("light 0 (lampNode): the position (1.000000, 2.000000, 3.000000) is outside the scene's bounds"),
            std::string::npos) << r.out;
  r = cpvs("bake " + path("lights.gltf") + " --sun-dir 0,-1,0 -r 1K -q -o " + path("lights.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  r = cpvs("inspect --json " + path("lights.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(parse(r)["plan"], plan);
  // The city has closed parts: the exit search runs; its receivers reach part of the grid.
  r = cpvs("plan city:3 --sun-elevation 35 -r 256 --tile-size 64 --receivers surfaces --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const json city = parse(r);
  EXPECT_GT(city["closed_parts"].get<int>(), 0);
  EXPECT_EQ(city["passes"][1]["runs"], true);
  EXPECT_EQ(city["receivers"]["kind"], "surfaces");
  EXPECT_GT(city["receivers"]["columns_read_share"].get<double>(), 0.0);
  EXPECT_EQ(city["tiles"]["total"], 16);
}

TEST_F(Cli, QueryOnePointAndACsv) {
  // Far above the city, sunlit; under the ground slab's middle, shadowed.
  CliRun lit = cpvs("query " + path("c.cpvs") + " --point 40,200,40");
  ASSERT_EQ(lit.status, 0) << lit.out;
  EXPECT_EQ(lit.out.rfind("lit", 0), 0u) << lit.out;
  CliRun dark = cpvs("query " + path("c.cpvs") + " --point 40,-5,40");
  ASSERT_EQ(dark.status, 0) << dark.out;
  EXPECT_EQ(dark.out.rfind("shadowed", 0), 0u) << dark.out;

  std::ofstream(path("p.csv")) << "x,y,z\n40,200,40\n40,-5,40\n# a comment\n\n40,200,40,0,1,0\n";
  CliRun many = cpvs("query " + path("c.cpvs") + " --points " + path("p.csv") + " --pcf 3");
  ASSERT_EQ(many.status, 0) << many.out;
  EXPECT_EQ(many.out, "x,y,z,visibility\n40,200,40,1\n40,-5,40,0\n40,200,40,1\n");
}

// A file baked for declared receivers says so on every query, warns for a filter wider
// than it was baked for, for a surface lookup without a normal, and for lookups that read
// only where no receiver reads (the coverage its plan records); plan draws that coverage.
TEST_F(Cli, QueryWarnsOutsideTheDeclaredReceivers) {
  // Two small squares far apart, facing up.
  std::ofstream(path("two.obj")) << "v 0 0 0\nv 0 0 1\nv 1 0 1\nv 1 0 0\nv 30 0 30\nv 30 0 31\nv 31 0 31\nv 31 0 30\n"
                                    "f 1 2 3 4\nf 5 6 7 8\n";
  CliRun r = cpvs("bake " + path("two.obj") + " --sun-dir 0.1,-1,0.1 -r 512 --receivers surfaces --receiver-pcf 3 -q -o " +
                  path("two.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  r = cpvs("query " + path("two.cpvs") + " --point 0.5,0,0.5 --normal 0,1,0");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("lit"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("baked for 'surfaces' receivers (lookups up to PCF 3)"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("warning"), std::string::npos) << r.out;
  r = cpvs("query " + path("two.cpvs") + " --point 15,0,15 --normal 0,1,0");  // between them: nobody reads there
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("outside the declared receivers"), std::string::npos) << r.out;
  r = cpvs("query " + path("two.cpvs") + " --point 0.5,0,0.5 --pcf 9");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("--pcf 9 is wider than the 3"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("this lookup has none"), std::string::npos) << r.out;
  std::ofstream(path("two.csv")) << "0.5,0,0.5,0,1,0\n15,0,15,0,1,0\n30.5,0,30.5,0,1,0\n20,0,8,0,1,0\n";
  r = cpvs("query " + path("two.cpvs") + " --points " + path("two.csv"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("2 of 4 points are outside the declared receivers (points 2, 4)"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("have no normal"), std::string::npos) << r.out;
  std::ofstream(path("two-mixed.csv")) << "0.5,0,0.5,0,1,0\n30.5,0,30.5\n";
  r = cpvs("query " + path("two.cpvs") + " --points " + path("two-mixed.csv"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("1 of 2 points have no normal"), std::string::npos) << r.out;
  // A file baked for everywhere warns about nothing.
  r = cpvs("query " + path("c.cpvs") + " --points " + path("two.csv"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(r.out.find("note"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("warning"), std::string::npos) << r.out;

  r = cpvs("plan " + path("two.obj") + " --sun-dir 0.1,-1,0.1 -r 512 --tile-size 64 --receivers surfaces --coverage-png " +
           path("coverage.png"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("receiver coverage: "), std::string::npos) << r.out;
  const Image img = readPng(path("coverage.png"));
  ASSERT_EQ(img.width, 512);
  ASSERT_EQ(img.height, 512);
  size_t orange = 0, black = 0;
  for (const Rgb& p : img.pixels) {
    orange += p.r > 0.9f && p.b < 0.1f;
    black += p.r < 0.01f && p.g < 0.01f;
  }
  EXPECT_GT(orange, 10u);       // the squares and their lookups' reach
  EXPECT_GT(black, 512u * 256);  // most tiles hold no triangle
}

TEST_F(Cli, RenderWritesPicturesAndReference) {
  CliRun r = cpvs("render " + path("c.cpvs") + " city:3 --size 64x48 --reference --out " + path("shot.png"));
  ASSERT_EQ(r.status, 0) << r.out;
  for (const char* f : {"shot.png", "shot.exr", "shot-reference.png", "shot-reference.exr", "shot-diff.png",
                        "shot-diff.exr"})
    EXPECT_TRUE(fs::exists(path(f))) << f;
  Image img = readPng(path("shot.png"));
  EXPECT_EQ(img.width, 64);
  EXPECT_EQ(img.height, 48);
  std::ifstream exr(path("shot.exr"), std::ios::binary);
  char magic[4] = {};
  exr.read(magic, 4);
  EXPECT_EQ(std::string(magic, 4), std::string("\x76\x2f\x31\x01", 4)) << "OpenEXR magic number";
  // The picture is not blank: the sky is blue and the city is grey.
  float minL = 1, maxL = 0;
  for (const Rgb& p : img.pixels) {
    minL = std::min(minL, p.g);
    maxL = std::max(maxL, p.g);
  }
  EXPECT_LT(minL, 0.2f);
  EXPECT_GT(maxL, 0.3f);
}

// --dynamic: a mesh over the city casts its shadow through a TOP tree times the CPVS:
// darker pixels than the bake alone, within a few pixels of exact rays, the same picture
// on a device, an animation of --frames; bad placements refused.
TEST_F(Cli, RenderWithADynamicCaster) {
  const std::string duck = "/usr/share/assimp/models/Collada/duck.dae";
  const std::string view = " city:3 --size 160x100 --camera 75,110,-20,38,55,40,45 ";
  CliRun r = cpvs("render " + path("c.cpvs") + view + "--dynamic " + duck + " --reference --frames 3 -o " + path("duck.png"));
  ASSERT_EQ(r.status, 0) << r.out;
  for (const char* f : {"duck.png", "duck.exr", "duck-reference.png", "duck-diff.png", "duck-animation.png"})
    EXPECT_TRUE(fs::exists(path(f))) << f;
  EXPECT_NE(r.out.find("4212 triangles"), std::string::npos) << r.out;
  const size_t at = r.out.find(" sunward pixels differ (");
  ASSERT_NE(at, std::string::npos) << r.out;
  EXPECT_LT(std::stod(r.out.substr(at + 24)), 3.0) << "percent of pixels off exact rays: " << r.out;
  r = cpvs("render " + path("c.cpvs") + view + "-o " + path("noduck.png"));
  ASSERT_EQ(r.status, 0) << r.out;
  const Image with = readPng(path("duck.png")), without = readPng(path("noduck.png"));
  ASSERT_EQ(with.pixels.size(), without.pixels.size());
  size_t darker = 0;
  for (size_t i = 0; i < with.pixels.size(); ++i) darker += with.pixels[i].g < without.pixels[i].g - 0.05f;
  EXPECT_GT(darker, 100u) << "the duck's shadow (and the duck) darken the picture";
  r = cpvs("render " + path("c.cpvs") + view + "--gpu --dynamic " + duck + " --frames 3 -o " + path("duck-gpu.png"));
  ASSERT_EQ(r.status, 0) << r.out;
  std::ifstream x(path("duck.png"), std::ios::binary), y(path("duck-gpu.png"), std::ios::binary);
  const std::string a((std::istreambuf_iterator<char>(x)), {}), b((std::istreambuf_iterator<char>(y)), {});
  EXPECT_EQ(a, b) << "the device's picture is the CPU's";
  for (const auto& [args, message] : std::vector<std::pair<std::string, std::string>>{
           {"--dynamic " + duck + ":1,2,3,0", "the scale must be positive"},
           {"--dynamic " + duck + ":1,2,3,4,5,6", "a placement is X,Y,Z"},
           {"--frames 3", "--frames: the frames of a --dynamic"},
           {"--dynamic " + duck + " --fog 0.02,0.01", "one at a time"},
           {"--dynamic " + path("no-such-mesh.obj"), "no-such-mesh.obj"}}) {
    r = cpvs("render " + path("c.cpvs") + view + args + " -o " + path("bad.png"));
    EXPECT_NE(r.status, 0) << args;
    EXPECT_NE(r.out.find(message), std::string::npos) << args << ": " << r.out;
  }
}

// Glass: the plan says it, bake stores the tree of the panes beside the CPVS, inspect shows
// it, query answers the light through them (the device's to the bit), verify checks the
// CPVS against the opaque part and the tree against the scene, and render tints the
// shadows (the same picture on the device).
TEST_F(Cli, TranslucentCastersFromBakeToPicture) {
  const std::string glb = path("glass.glb");
  testing::writeGlb(testing::glassCity(), glb);
  CliRun r = cpvs("plan " + glb + " --sun-dir 0.3,-1,0.2 -r 512");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("translucent casters: 3 meshes, 16 triangles"), std::string::npos) << r.out;
  r = cpvs("plan city:2 --sun-dir 0.3,-1,0.2 -r 512");
  EXPECT_NE(r.out.find("translucent casters: none"), std::string::npos) << r.out;
  r = cpvs("bake " + glb + " --sun-dir 0.3,-1,0.2 -r 512 -q -o " + path("glass.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  r = cpvs("inspect " + path("glass.cpvs"));
  EXPECT_NE(r.out.find("translucent casters: a TOP tree of 16 frusta"), std::string::npos) << r.out;
  r = cpvs("inspect " + path("glass.cpvs") + " --json");
  EXPECT_EQ(nlohmann::json::parse(r.out)["translucent"]["frusta"], 16) << r.out;
  // Points under the panes and the box (a 4 x 4 grid over the scene at mid height) on the CPU and the device.
  std::string csv = "x,y,z,nx,ny,nz\n";
  for (int i = 0; i < 16; ++i) csv += std::to_string(8 + 5 * (i % 4)) + ",2," + std::to_string(8 + 5 * (i / 4)) + ",0,1,0\n";
  std::ofstream(path("under.csv")) << csv;
  r = cpvs("query " + path("glass.cpvs") + " --points " + path("under.csv"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("x,y,z,visibility,transmittance_r,transmittance_g,transmittance_b"), std::string::npos) << r.out;
  CliRun onGpu = cpvs("query " + path("glass.cpvs") + " --points " + path("under.csv") + " --gpu");
  ASSERT_EQ(onGpu.status, 0) << onGpu.out;
  EXPECT_NE(onGpu.out.find(r.out.substr(r.out.find("x,y,z"))), std::string::npos) << "the device's answers are the CPU's";
  r = cpvs("verify " + path("glass.cpvs") + " " + glb + " -n 20000");
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("the file's tree is the scene's, node for node"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("walk equals the brute force"), std::string::npos) << r.out;
  // An artifact of the scene without its glass is not the glass scene's.
  r = cpvs("verify " + path("c.cpvs") + " " + glb);
  EXPECT_NE(r.status, 0);
  const std::string view = " --size 160x100 --camera 60,90,-30,20,0,20,50 ";
  r = cpvs("render " + path("glass.cpvs") + " " + glb + view + "--reference -o " + path("glass.png"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("through the translucent casters"), std::string::npos) << r.out;
  const Image picture = readPng(path("glass.png"));
  size_t tinted = 0;  // the green pane lets more green than red or blue through
  for (const Rgb& c : picture.pixels) tinted += c.g > c.r * 1.15f && c.g > c.b * 1.3f;
  EXPECT_GT(tinted, 50u) << "green light under the green pane";
  r = cpvs("render " + path("glass.cpvs") + " " + glb + view + "--gpu -o " + path("glass-gpu.png"));
  ASSERT_EQ(r.status, 0) << r.out;
  std::ifstream x(path("glass.png"), std::ios::binary), y(path("glass-gpu.png"), std::ios::binary);
  EXPECT_EQ(std::string((std::istreambuf_iterator<char>(x)), {}), std::string((std::istreambuf_iterator<char>(y)), {}));
  r = cpvs("render " + path("glass.cpvs") + " " + glb + view + "--fog 0.02,0.01 -o " + path("bad.png"));
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.out.find("translucent casters"), std::string::npos) << r.out;
  // A scene of glass alone (an OBJ's dissolve): an all-lit CPVS, the light through the
  // pane, verified; nothing to draw it on.
  std::ofstream(path("pane.mtl")) << "newmtl glass\nd 0.5\n";
  std::ofstream(path("pane.obj")) << "mtllib pane.mtl\nv -2 2 -2\nv 2 2 -2\nv 2 2 2\nv -2 2 2\nusemtl glass\nf 1 3 2\nf 1 4 3\n";
  r = cpvs("bake " + path("pane.obj") + " --sun-dir 0.2,-1,0.1 -r 64 -q -o " + path("pane.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  r = cpvs("query " + path("pane.cpvs") + " --point 0,0,0");
  EXPECT_NE(r.out.find("lit  visibility 1"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("transmittance 0.5 0.5 0.5"), std::string::npos) << r.out;
  r = cpvs("verify " + path("pane.cpvs") + " " + path("pane.obj") + " -n 2000");
  EXPECT_EQ(r.status, 0) << r.out;
  r = cpvs("render " + path("pane.cpvs") + " " + path("pane.obj") + " -o " + path("pane.png"));
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.out.find("nothing to draw"), std::string::npos) << r.out;
}

// --gpu (lavapipe here): the same picture bytes and the same CSV as the CPU path; no
// Vulkan loader: exit status 5 and a message that says what to do.
TEST_F(Cli, GpuLookupsGiveTheSamePictureAndAnswers) {
  for (const char* pcf : {"1", "9"}) {
    const std::string cpu = path(std::string("cpu") + pcf + ".png"), gpu = path(std::string("gpu") + pcf + ".png");
    CliRun a = cpvs("render " + path("c.cpvs") + " city:3 --size 160x100 --pcf " + pcf + " --out " + cpu);
    ASSERT_EQ(a.status, 0) << a.out;
    CliRun b = cpvs("render " + path("c.cpvs") + " city:3 --size 160x100 --gpu --pcf " + pcf + " --out " + gpu);
    ASSERT_EQ(b.status, 0) << b.out;
    EXPECT_NE(b.out.find("Vulkan"), std::string::npos) << b.out;
    std::ifstream x(cpu, std::ios::binary), y(gpu, std::ios::binary);
    const std::string bytesA((std::istreambuf_iterator<char>(x)), {}), bytesB((std::istreambuf_iterator<char>(y)), {});
    EXPECT_GT(bytesA.size(), 1000u);
    EXPECT_EQ(bytesA, bytesB) << "PCF " << pcf << ": the GPU picture differs from the CPU's";
  }
  std::ofstream csv(path("g.csv"));
  csv << "x,y,z,nx,ny,nz\n";
  for (int i = 0; i < 400; ++i) csv << (i * 7) % 90 << "," << (i % 13) * 3 - 5 << "," << (i * 11) % 90 << ",0,1,0\n";
  csv.close();
  CliRun cpuCsv = cpvs("query " + path("c.cpvs") + " --points " + path("g.csv") + " --pcf 5");
  CliRun gpuCsv = cpvs("query " + path("c.cpvs") + " --points " + path("g.csv") + " --pcf 5 --gpu");
  ASSERT_EQ(cpuCsv.status, 0) << cpuCsv.out;
  ASSERT_EQ(gpuCsv.status, 0) << gpuCsv.out;
  const std::string header = "x,y,z,visibility";
  ASSERT_NE(gpuCsv.out.find(header), std::string::npos);
  EXPECT_EQ(cpuCsv.out, gpuCsv.out.substr(gpuCsv.out.find(header)));  // after "Looking up on ..."
  CliRun none = testing::runShell("CPVS_VULKAN_LOADER=/nonexistent/libvulkan.so.1 timeout 120 '" CPVS_CLI "' query " +
                                  path("c.cpvs") + " --point 1,2,3 --gpu 2>&1");
  EXPECT_EQ(none.status, 5) << none.out;
  EXPECT_NE(none.out.find("no Vulkan loader"), std::string::npos) << none.out;
  EXPECT_NE(none.out.find("leave out --gpu"), std::string::npos) << none.out;
}

// `cpvs sun`: the SPA paper's example through the command line, night as a state (no
// direction), and bad places and times refused with status 2.
TEST_F(Cli, SunJsonContractAndNight) {
  CliRun r = cpvs("sun --lat 39.742476 --lon -105.1786 --height 1830.14 --time 2003-10-17T12:30:30-07:00 "
                  "--pressure 820 --temperature 11 --delta-t 67 --json");
  ASSERT_EQ(r.status, 0) << r.out;
  json j = parse(r);
  EXPECT_EQ(j["time_utc"], "2003-10-17T19:30:30Z");
  EXPECT_NEAR(j["zenith_deg"].get<double>(), 50.11162, 0.001);
  EXPECT_NEAR(j["azimuth_deg"].get<double>(), 194.34024, 0.001);
  EXPECT_NEAR(j["elevation_deg"].get<double>(), 90 - 50.11162, 0.001);
  EXPECT_EQ(j["night"], false);
  ASSERT_EQ(j["direction"].size(), 3u);
  EXPECT_LT(j["direction"][1].get<double>(), 0);  // down into the scene (Y up)
  CliRun night = cpvs("sun --lat 80 --lon 0 --time 2024-12-21T12:00Z --json");
  ASSERT_EQ(night.status, 0) << night.out;
  EXPECT_EQ(parse(night)["night"], true);
  EXPECT_TRUE(parse(night)["direction"].is_null());
  CliRun text = cpvs("sun --lat 80 --lon 0 --time 2024-12-21T12:00Z");
  EXPECT_NE(text.out.find("night"), std::string::npos) << text.out;
  for (const char* bad : {"sun --lat 95 --lon 0 --time 2024-12-21T12:00Z", "sun --lat 10 --lon 0 --time 2024-12-21T12:00",
                          "sun --lat 10 --lon 0 --time 2024-12-21T12:00Z --up +Y --north +Y"}) {
    CliRun b = cpvs(bad);
    EXPECT_EQ(b.status, 2) << bad << ": " << b.out;
  }
}

// `contact-sheet`: versions (here two bakes under two suns) side by side, and as an APNG
// whose chunks are in order, with valid CRCs, one fcTL per frame, sequence numbers 0..n-1,
// and whose first frame a plain PNG reader shows.
TEST_F(Cli, ContactSheetAndAnimation) {
  const std::string dir = path("versions");
  fs::create_directories(dir);
  for (const char* v : {"1", "2"}) {
    CliRun b = cpvs(std::string("bake city:3 --sun-elevation ") + (v[0] == '1' ? "25" : "60") +
                    " -r 256 -q -o " + dir + "/version-00000" + v + ".cpvs");
    ASSERT_EQ(b.status, 0) << b.out;
  }
  CliRun r = cpvs("contact-sheet " + dir + " city:3 --size 64x40 --columns 2 --out " + path("sheet.png") +
                  " --animation " + path("anim.png") + " --delay-ms 250");
  ASSERT_EQ(r.status, 0) << r.out;
  const Image sheet = readPng(path("sheet.png"));
  EXPECT_EQ(sheet.width, 128);
  EXPECT_EQ(sheet.height, 40);
  const Image first = readPng(path("anim.png"));
  EXPECT_EQ(first.width, 64);
  std::ifstream in(path("anim.png"), std::ios::binary);
  const std::string png((std::istreambuf_iterator<char>(in)), {});
  ASSERT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  auto be = [&](size_t at) {
    return uint32_t(uint8_t(png[at])) << 24 | uint32_t(uint8_t(png[at + 1])) << 16 | uint32_t(uint8_t(png[at + 2])) << 8 |
           uint32_t(uint8_t(png[at + 3]));
  };
  std::vector<std::string> types;
  std::vector<uint32_t> sequence;
  for (size_t at = 8; at + 12 <= png.size();) {
    const uint32_t n = be(at);
    const std::string type = png.substr(at + 4, 4);
    ASSERT_LE(at + 12 + n, png.size());
    const uint32_t crc = uint32_t(crc32(0, reinterpret_cast<const Bytef*>(png.data() + at + 4), uInt(n + 4)));
    EXPECT_EQ(be(at + 8 + n), crc) << type;
    if (type == "fcTL" || type == "fdAT") sequence.push_back(be(at + 8));
    if (type == "acTL") {
      EXPECT_EQ(be(at + 8), 2u);
    }
    types.push_back(type);
    at += 12 + n;
  }
  EXPECT_EQ(types, (std::vector<std::string>{"IHDR", "sRGB", "acTL", "fcTL", "IDAT", "fcTL", "fdAT", "IEND"}));
  EXPECT_EQ(sequence, (std::vector<uint32_t>{0, 1, 2}));
  CliRun none = cpvs("contact-sheet " + path("no-such-folder") + " city:3 --out " + path("x.png"));
  EXPECT_EQ(none.status, 2) << none.out;
}

// Bad input: exit status 2 and a message that names what is wrong.
struct BadCase {
  const char* args;
  const char* message;
};

TEST_F(Cli, BadInputIsRejectedClearly) {
  std::ofstream(path("empty.obj")) << "# nothing\n";
  std::ofstream(path("nan.obj")) << "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n";
  auto bytes = readFile(path("c.cpvs"));
  {
    std::ofstream t(path("truncated.cpvs"), std::ios::binary);
    t.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size() / 2));
    std::ofstream c(path("corrupt.cpvs"), std::ios::binary);
    bytes[bytes.size() / 2] ^= 0x40;
    c.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  }
  const std::string out = " -o " + path("x.cpvs");
  const std::vector<BadCase> cases{
      {"bake /no/such/scene.obj --sun-dir 0,-1,0", "/no/such/scene.obj"},
      {"bake city --sun-dir 0,-1,0 -r 3", "resolution"},
      {"bake city --sun-dir 0,-1,0 -r 5000", "power of two"},
      {"bake city --sun-dir 0,0,0", "zero vector"},
      {"bake city --sun-dir 1,nan,0", "--sun-dir"},
      {"bake city --sun-dir 0,-1", "--sun-dir"},
      {"bake city --sun-elevation -5", "elevation"},
      {"bake city --sun-elevation 30 --sun-dir 0,-1,0", "not both"},
      {"bake city", "--sun-dir"},
      {"bake city:x --sun-dir 0,-1,0", "city:x"},
      {"bake city --sun-dir 0,-1,0 --tile-size 100", "--tile-size"},
      {"bake ", "empty.obj"},
      {"bake ", "nan.obj"},
      {"inspect ", "truncated.cpvs"},
      {"inspect ", "corrupt.cpvs"},
      {"inspect /no/such/file.cpvs", "/no/such/file.cpvs"},
      {"verify ", "not the scene"},
      {"query ", "--point"},
      {"query ", "--point"},
      {"bake city --sun-dir 0,-1,0 --receivers sideways", "--receivers"},
      {"bake city --sun-dir 0,-1,0 --receivers surfaces --receiver-box 0,0,0,1,1,1", "needs --receivers volume"},
      {"bake city --sun-dir 0,-1,0 --receivers volume", "needs a volume"},
      {"bake city --sun-dir 0,-1,0 --receivers volume --receiver-box 0,0,0,1,1", "MINX"},
      {"bake city --sun-dir 0,-1,0 --receivers surfaces --receiver-pcf 4", "must be odd"},
      {"bake city --sun-dir 0,-1,0 --receivers surfaces:x.obj", "only 'volume' and 'cameras' take a file"},
      {"submit --server 127.0.0.1:1 city --sun-dir 0,-1,0 --receivers volume", "needs volume_scene_hash, boxes or ground_layer"},
      {"submit --server 127.0.0.1:1 city --sun-dir 0,-1,0 --receivers surfaces --receiver-pcf 6", "must be odd"},
      {"bake city --sun-dir 0,-1,0 --receivers cameras --camera-region 0,0,0,1,1,1", "view distance"},
      {"bake city --sun-dir 0,-1,0 --receivers surfaces --view-distance 5", "need --receivers cameras"},
      {"submit --server 127.0.0.1:1 city --sun-dir 0,-1,0 --receivers cameras:/nonexistent/cams.json", "/nonexistent/cams.json"},
      {"submit --server 127.0.0.1:1 city --sun-dir 0,-1,0 --receivers cameras --camera-region 0,0,0,1,1,1 --view-distance 5 "
       "--camera-spacing 2", "camera_spacing and camera_rays are for CAMERA_VISIBILITY_SAMPLED only"},
      {"bake city --sun-dir 0,-1,0 --receivers cameras --camera-region 0,0,0,1,1,1 --view-distance 5 --camera-visibility "
       "sampled --camera-rays -3", "--camera-rays must be 0"},
      {"bake city --sun-dir 0,-1,0 --receivers surfaces --ground-layer 2", "needs --receivers volume or cameras"},
      {"bake city --sun-dir 0,-1,0 --receivers volume --ground-layer 3:1", "0 <= FROM < TO"},
      {"bake city --sun-dir 0,-1,0 --receivers volume --ground-layer :2", "0 <= FROM < TO"},
      {"bake city --sun-dir 0,-1,0 --receivers volume --ground-layer 1,5:2", "0 <= FROM < TO"},
      {"bake city --sun-dir 0,-1,0 --receivers volume --receiver-box 0,0,0,1,1,1 --ground-slope 30", "needs --ground-layer"},
      {"bake city --sun-dir 0,-1,0 --receivers volume --ground-layer 1e9", "taller than twice the scene's grid"},
      {"bake city --sun-dir 0,-1,0 --receivers volume --ground-layer 2 --ground-slope 95", "below 90"},
      {"submit --server 127.0.0.1:1 city --spot 1,2,3:0,-1,0:30 --sun-dir 0,-1,0", "the sun flags are for a sun bake"},
      {"submit --server 127.0.0.1:1 city --spot 1,2,3:0,-1,0:30 --resolution 1K", "--resolution is the sun's"},
      {"submit --server 127.0.0.1:1 city --spot 1,2,3:0,-1,0:30 --receivers volume", "RECEIVERS_VOLUME needs"},
      {"submit --server 127.0.0.1:1 city --sun-dir 0,-1,0 --pointer-grid 2", "are for local lights"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    std::string args = cases[i].args;
    if (i == 11) args += path("empty.obj") + " --sun-dir 0,-1,0";
    if (i == 12) args += path("nan.obj") + " --sun-dir 0,-1,0";
    if (i == 13) args += path("truncated.cpvs");
    if (i == 14) args += path("corrupt.cpvs");
    if (i == 16) args += path("c.cpvs") + " city:4";
    if (i == 17) args += path("c.cpvs");
    if (i == 18) args += path("c.cpvs") + " --point 1,2,3 --points " + path("p.csv");
    if (args.starts_with("bake")) args += out;
    CliRun r = cpvs(args);
    EXPECT_EQ(r.status, 2) << args << "\n" << r.out;
    EXPECT_NE(r.out.find(cases[i].message), std::string::npos) << args << "\n" << r.out;
    EXPECT_EQ(r.out.find("internal error"), std::string::npos) << args << "\n" << r.out;
  }
  EXPECT_FALSE(fs::exists(path("x.cpvs"))) << "a failed bake leaves no output";

  // An output path whose folder is not there is refused before any work is done.
  struct BadOutput {
    std::string args, message;
  };
  const std::vector<BadOutput> outputs{
      {"bake city:3:5 --scene-lights -o " + path("no/such/x.cpvs"), "the folder " + path("no/such") + " does not exist"},
      {"bake city:4 --sun-dir 0,-1,0 -o " + path("c.cpvs") + "/x.cpvs", path("c.cpvs") + " is not a folder"},
      {"render " + path("c.cpvs") + " city:4 -o " + path("no/x.png"), "--out " + path("no/x.png") + ": the folder"},
  };
  for (const BadOutput& c : outputs) {
    CliRun r = cpvs(c.args);
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.out;
    EXPECT_NE(r.out.find(c.message), std::string::npos) << c.args << "\n" << r.out;
    EXPECT_EQ(r.out.find("grids ("), std::string::npos) << "nothing was baked: " << r.out;
    EXPECT_EQ(r.out.find("tiles ("), std::string::npos) << "nothing was baked: " << r.out;
  }
}

// Local lights: a bundle from a lights file and flags, inspected, queried per light and
// verified per light; bad lights and mixed-up files get clear errors.
TEST_F(Cli, LightBundlesBakeInspectQueryAndVerify) {
  std::ofstream(path("lights.json")) << R"({"lights": [
    {"kind": "LIGHT_SPOT", "name": "flood", "position": {"x": 30, "y": 55, "z": 30}, "direction": {"x": 0.2, "y": -1, "z": 0.1},
     "coneDeg": 40, "colour": {"x": 1, "y": 0.9, "z": 0.7}},
    {"kind": "LIGHT_POINT", "name": "bulb", "position": {"x": 40, "y": 56, "z": 36}, "range": 70, "resolution": "256"}]})";
  CliRun r = cpvs("bake city:3 --lights " + path("lights.json") + " --spot 60,54,20:-0.3,-1,0.2:30:80 --footprint 0.4 --json -o " +
                  path("lamps.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  const json b = parse(r);
  ASSERT_EQ(b["lights"].size(), 3u);
  EXPECT_EQ(b["grids"], 8);
  EXPECT_EQ(b["lights"][0]["name"], "flood");
  EXPECT_EQ(b["lights"][1]["kind"], "point");
  EXPECT_EQ(b["lights"][1]["grids"].size(), 6u);
  EXPECT_EQ(b["lights"][1]["grids"][0]["resolution"], 256);
  EXPECT_EQ(b["lights"][2]["range"], 80);
  EXPECT_LE(b["pool_bytes"].get<uint64_t>(), b["separate_bytes"].get<uint64_t>());
  EXPECT_GT(b["shadow_map_bytes"].get<uint64_t>(), b["pool_bytes"].get<uint64_t>());

  // `plan` with the same flags: the grids the bake planned, one line per light, no bake.
  r = cpvs("plan city:3 --lights " + path("lights.json") + " --spot 60,54,20:-0.3,-1,0.2:30:80 --footprint 0.4 --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const json p = parse(r);
  EXPECT_EQ(p["lights"], 3);
  ASSERT_EQ(p["plan"]["grids"].size(), 8u);
  for (size_t k = 0; k < 8; ++k) {
    const json& g = p["plan"]["grids"][k];
    const json& baked = b["lights"][k == 0 ? 0 : k < 7 ? 1 : 2]["grids"][k == 0 || k == 7 ? 0 : k - 1];
    EXPECT_EQ(g["resolution"], baked["resolution"]) << "grid " << k;
    EXPECT_EQ(g["near"], baked["near"]) << "grid " << k;
    EXPECT_EQ(g["far"], baked["far"]) << "grid " << k;
  }
  r = cpvs("plan city:3 --lights " + path("lights.json") + " --spot 60,54,20:-0.3,-1,0.2:30:80 --footprint 0.4");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("3 local lights, 8 grids"), std::string::npos) << r.out;
  for (const char* row : {"\n  0     flood", "\n  1     bulb               point", "\n  2                        spot"})
    EXPECT_NE(r.out.find(row), std::string::npos) << row << " in " << r.out;
  r = cpvs("plan city:3 --spot 60,54,20:-0.3,-1,0 --json");
  EXPECT_EQ(r.status, 2) << "a malformed light: " << r.out;
  EXPECT_NE(r.out.find("--spot"), std::string::npos) << r.out;
  r = cpvs("plan city:3 --point 60,54,20 --sun-elevation 30 --sun-azimuth 10");
  EXPECT_EQ(r.status, 2) << r.out;
  // A shallower pointer grid: recorded per grid, the same answers.
  r = cpvs("bake city:3 --lights " + path("lights.json") + " --spot 60,54,20:-0.3,-1,0.2:30:80 --footprint 0.4 "
           "--pointer-grid 1 --json -o " + path("lamps-flat.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(parse(r)["lights"][1]["grids"][3]["pointer_grid_levels"], 1);
  EXPECT_EQ(b["lights"][1]["grids"][3]["pointer_grid_levels"], 5);
  EXPECT_EQ(cpvs("query " + path("lamps-flat.cpvs") + " --point 31,0.01,30 --normal 0,1,0 --pcf 9").out,
            cpvs("query " + path("lamps.cpvs") + " --point 31,0.01,30 --normal 0,1,0 --pcf 9").out);
  EXPECT_EQ(cpvs("bake city:3 --sun-elevation 30 --sun-azimuth 10 --pointer-grid 2 -o " + path("sun-flat.cpvs")).status, 2);

  r = cpvs("inspect --json " + path("lamps.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  const json i = parse(r);
  EXPECT_EQ(i["format_version"], 4);
  EXPECT_EQ(i["pool_bytes"], b["pool_bytes"]);
  EXPECT_EQ(i["lights"][2]["bytes"], b["lights"][2]["bytes"]);
  r = cpvs("inspect " + path("lamps.cpvs"));
  EXPECT_NE(r.out.find("a light bundle"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("bulb"), std::string::npos) << r.out;

  r = cpvs("query " + path("lamps.cpvs") + " --point 31,0.01,30 --normal 0,1,0");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("light 0 (flood)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("light 2"), std::string::npos) << r.out;
  r = cpvs("query " + path("lamps.cpvs") + " --point 31,0.01,30 --light 1 --pcf 5");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(r.out.find("light 0"), std::string::npos) << r.out;
  std::ofstream(path("lamp_points.csv")) << "31,0.01,30,0,1,0\n-50,-50,-50,0,1,0\n";
  r = cpvs("query " + path("lamps.cpvs") + " --points " + path("lamp_points.csv"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("x,y,z,light0,light1,light2"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("-50,-50,-50,0,0,0"), std::string::npos) << "no light reaches outside the cones: " << r.out;

  r = cpvs("verify --json " + path("lamps.cpvs") + " city:3 --samples 6000");
  ASSERT_EQ(r.status, 0) << r.out;
  const json v = parse(r);
  ASSERT_EQ(v["lights"].size(), 3u);
  EXPECT_EQ(v["mismatch_elsewhere_count"], 0);
  EXPECT_EQ(v["oracles_disagree_elsewhere_count"], 0);
  for (const json& l : v["lights"]) {
    EXPECT_GT(l["samples"].get<uint64_t>(), 500u) << l;
    EXPECT_GT(l["lit"].get<uint64_t>(), 50u) << "each light lights some of the city: " << l;
  }

  // Baked for surface receivers: recorded, shown, smaller, and verified on the declared sides.
  r = cpvs("bake city:3 --lights " + path("lights.json") + " --spot 60,54,20:-0.3,-1,0.2:30:80 --footprint 0.4 "
           "--receivers surfaces --receiver-pcf 5 --json -o " + path("lamps-surfaces.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  const json declared = parse(r);
  EXPECT_EQ(declared["receivers"]["kind"], "surfaces");
  EXPECT_EQ(declared["receivers"]["pcf"], 5);
  EXPECT_LT(declared["pool_bytes"].get<uint64_t>(), b["pool_bytes"].get<uint64_t>());
  EXPECT_EQ(b["receivers"]["kind"], "everywhere");
  r = cpvs("inspect " + path("lamps-surfaces.cpvs"));
  EXPECT_NE(r.out.find("receivers: surfaces, PCF up to 5"), std::string::npos) << r.out;
  r = cpvs("plan city:3 --lights " + path("lights.json") + " --receivers surfaces");
  EXPECT_NE(r.out.find("receivers: surfaces, PCF up to 9"), std::string::npos) << r.out;
  r = cpvs("verify --json " + path("lamps-surfaces.cpvs") + " city:3 --samples 6000");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(parse(r)["mismatch_elsewhere_count"], 0);
  r = cpvs("verify " + path("lamps-surfaces.cpvs") + " city:3 --receivers surfaces-two-sided");
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("was baked for 'surfaces'"), std::string::npos) << r.out;

  r = cpvs("render " + path("lamps.cpvs") + " city:3 --size 160x100 --pcf 5 --out " + path("night.png"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("3 lights"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("lights per tile"), std::string::npos) << r.out;
  for (const char* f : {"night.png", "night.exr", "night-tiles.png"}) EXPECT_TRUE(fs::exists(path(f))) << f;
  const Image night = readPng(path("night.png"));
  EXPECT_EQ(night.width, 160);
  float brightest = 0;
  for (const Rgb& p : night.pixels) brightest = std::max(brightest, p.r);
  EXPECT_GT(brightest, 0.2f) << "the lights light the city";
  // With the lookups on a device (lavapipe): the same picture, bit for bit.
  r = cpvs("render " + path("lamps.cpvs") + " city:3 --size 160x100 --pcf 5 --gpu --out " + path("night-gpu.png"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("lookups on "), std::string::npos) << r.out;
  EXPECT_EQ(readFile(path("night-gpu.exr")), readFile(path("night.exr")));
  EXPECT_EQ(readFile(path("night-gpu.png")), readFile(path("night.png")));

  // The scene's own lights: the city's street lamps; COLLADA's (assimp-testmodels), whose
  // spot cone assimp reads as 135 degrees, baked as a point light.
  r = cpvs("bake city:3 --scene-lights --footprint 0.2 --json -o " + path("street.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  const json street = parse(r);
  ASSERT_GE(street["lights"].size(), 3u);
  EXPECT_EQ(street["lights"][0]["name"], "lamp 0");
  EXPECT_EQ(street["lights"][0]["cone_deg"], 60);
  r = cpvs("bake /usr/share/assimp/models/Collada/lights.dae --scene-lights --footprint 0.1 --json -o " + path("dae.cpvs"));
  ASSERT_EQ(r.status, 0) << r.out;
  const json dae = parse(r);
  ASSERT_EQ(dae["lights"].size(), 3u) << "a point, a spot and an area light COLLADA calls a point";
  EXPECT_EQ(dae["lights"][1]["name"], "Spot");
  EXPECT_EQ(dae["lights"][1]["kind"], "point");
  r = cpvs("verify " + path("dae.cpvs") + " /usr/share/assimp/models/Collada/lights.dae --samples 3000");
  EXPECT_EQ(r.status, 0) << r.out;

  // Bad lights and mixed-up files.
  std::ofstream(path("bad_lights.json")) << R"({"lights": [{"kind": "LIGHT_SPOT", "position": {"x": 1}, "shape": "round"}]})";
  std::string many = R"({"lights": [)";
  for (int k = 0; k < 5000; ++k) many += std::string(k ? "," : "") + R"({"kind": "LIGHT_POINT", "position": {"x": 30, "y": 30, "z": 30}})";
  std::ofstream(path("many_lights.json")) << many << "]}";
  const std::vector<BadCase> cases{
      {"bake city:3 --lights BAD", "not a lights file"},
      {"bake city:3 --lights MANY", "at most 4096"},
      {"bake city:3 --spot 30,50,30:0,-1,0:0", "cone"},
      {"bake city:3 --spot 30,50,30:0,-1,0", "X,Y,Z:DX,DY,DZ:CONE"},
      {"bake city:3 --spot 3000,50,30:0,-1,0:30", "outside the scene's bounds"},
      {"bake city:3 --point 30,50,30 --sun-dir 0,-1,0", "the sun flags are for a sun bake"},
      {"bake city:3 --point 30,50,30 --receivers volume", "'volume' needs a volume"},
      {"query LAMPS --point 1,2,3 --light 9", "give all or a light index"},
      {"query LAMPS --point 1,2,3 --gpu", "on the CPU"},
      {"query SUN --point 1,2,3 --light 0", "has the sun only"},
      {"verify LAMPS city:4", "not the scene"},
      {"render LAMPS city:3 --reference --out N.png", "verify checks a light bundle"},
  };
  for (const BadCase& c : cases) {
    std::string args = c.args;
    auto put = [&](const std::string& key, const std::string& file) {
      if (const size_t at = args.find(key); at != std::string::npos) args.replace(at, key.size(), path(file));
    };
    put("BAD", "bad_lights.json");
    put("MANY", "many_lights.json");
    put("LAMPS", "lamps.cpvs");
    put("SUN", "c.cpvs");
    if (args.starts_with("bake")) args += " -o " + path("y.cpvs");
    r = cpvs(args);
    EXPECT_EQ(r.status, 2) << args << "\n" << r.out;
    EXPECT_NE(r.out.find(c.message), std::string::npos) << args << "\n" << r.out;
  }
  EXPECT_FALSE(fs::exists(path("y.cpvs"))) << "a refused bake leaves no output";
}

TEST_F(Cli, HelpExplainsEveryCommand) {
  CliRun r = cpvs("--help");
  EXPECT_EQ(r.status, 0);
  for (const char* c : {"bake", "inspect", "query", "verify", "render", "plan"})
    EXPECT_NE(r.out.find(c), std::string::npos) << c;
  CliRun b = cpvs("bake --help");
  for (const char* o : {"--sun-dir", "--sun-elevation", "--resolution", "--closed", "--exit", "--cull", "--compress",
                        "--undefined", "--renderer", "--tile-size", "--threads", "--json"})
    EXPECT_NE(b.out.find(o), std::string::npos) << o;
}

}  // namespace
}  // namespace cpvs
