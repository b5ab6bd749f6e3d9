// Golden bakes: `cpvs bake` of three small scenes, each with a sun and options named here,
// must give the DAG whose XXH3-128 is committed in tests/bake/golden_bakes.txt. The other
// tests compare bakes with bakes (local against farm, amortized against one-shot), so a
// change that alters every DAG alike passes them; this one fails on any change of bytes.
//
// A change of bytes on purpose (a new rule, a new layout) refreshes the file:
//   CPVS_REFRESH_GOLDEN=1 ./build/tests/golden_bake_test
// and the commit says why the bytes changed.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "cpvs/base/hash.h"
#include "cpvs/io/cpvs_file.h"
#include "process_testing.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

namespace fs = std::filesystem;

const std::string kGoldenFile = CPVS_SOURCE_DIR "/tests/bake/golden_bakes.txt";

struct GoldenBake {
  const char* name;
  const char* scene;  // a procedural scene, or a path under shared/scenes
  bool shared;
  const char* flags;
};

// The rasterizer (the default renderer) gives the same bytes on every SIMD target; Embree's
// kernels differ by instruction set, so no golden bake uses it.
const GoldenBake kBakes[] = {
    {"city-1K", "city", false, "--sun-dir 0.3,-1,0.25 --resolution 1K"},
    {"city-1K-new-rule", "city", false, "--sun-dir 0.3,-1,0.25 --resolution 1K --undefined new"},
    {"bunny-2K", "stanford-bunny/bunny.obj", true,
     "--sun-elevation 40 --sun-azimuth 120 --resolution 2K --compress bottomup --tile-size 512"},
    {"house-2K", "openarena/oa_shouse.obj", true,
     "--sun-dir -0.31,-1,0.22 --resolution 2K --receivers surfaces --receiver-pcf 5"},
};

std::map<std::string, std::string> readGolden() {
  std::map<std::string, std::string> hashes;
  std::ifstream in(kGoldenFile);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream words(line);
    std::string name, hash;
    words >> name >> hash;
    hashes[name] = hash;
  }
  return hashes;
}

void writeGolden(const std::map<std::string, std::string>& hashes) {
  std::ofstream out(kGoldenFile);
  out << "# XXH3-128 of the packed DAG of each golden bake (tests/bake/golden_bake_test.cpp).\n"
         "# Refresh on purpose only: CPVS_REFRESH_GOLDEN=1 ./build/tests/golden_bake_test\n";
  for (const auto& [name, hash] : hashes) out << name << ' ' << hash << '\n';
}

/// The XXH3-128 of the packed DAG that `cpvs bake SCENE FLAGS` writes.
std::string bakeHash(const GoldenBake& bake, const std::string& scene, const fs::path& dir) {
  const std::string out = (dir / (std::string(bake.name) + ".cpvs")).string();
  const testing::CommandResult run = testing::runShell("timeout 300 '" CPVS_CLI "' bake '" + scene + "' " + bake.flags +
                                                       " -q --out '" + out + "' 2>&1");
  EXPECT_EQ(run.status, 0) << run.out;
  if (run.status != 0) return "";
  const CpvsArtifact artifact = readCpvs(out);
  const auto& words = artifact.packed.words();
  return contentHash(words.data(), words.size() * sizeof(uint32_t)).hex();
}

TEST(GoldenBake, DagBytesAreTheCommittedOnes) {
  const bool refresh = std::getenv("CPVS_REFRESH_GOLDEN") != nullptr;
  const std::string shared = testing::sharedScenesDir();
  if (shared.empty()) GTEST_SKIP() << "shared/scenes is not beside the project: the bunny and the house are there";
  const fs::path dir = fs::temp_directory_path() / ("cpvs_golden_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::map<std::string, std::string> golden = readGolden();
  ASSERT_TRUE(refresh || !golden.empty()) << "no golden hashes in " << kGoldenFile;
  for (const GoldenBake& bake : kBakes) {
    SCOPED_TRACE(bake.name);
    const std::string scene = bake.shared ? shared + "/" + bake.scene : bake.scene;
    const std::string hash = bakeHash(bake, scene, dir);
    if (refresh) {
      golden[bake.name] = hash;
      continue;
    }
    ASSERT_TRUE(golden.count(bake.name)) << kGoldenFile << " has no hash for " << bake.name;
    EXPECT_EQ(hash, golden[bake.name])
        << "the DAG of `cpvs bake " << bake.scene << ' ' << bake.flags << "` changed. If the change of bytes is "
        << "intended, refresh the hashes with CPVS_REFRESH_GOLDEN=1 ./build/tests/golden_bake_test and commit "
        << "tests/bake/golden_bakes.txt saying why the bytes changed; if not, the change broke the bake.";
  }
  if (refresh) {
    writeGolden(golden);
    std::printf("golden bakes: wrote %zu hashes to %s\n", golden.size(), kGoldenFile.c_str());
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace cpvs
