// What the benchmark programs share: the machine they ran on, the named scenes, numbers
// on the command line and in tables.
#pragma once

#include <algorithm>
#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "cpvs/base/vec3.h"
#include "cpvs/scene/scene.h"

namespace cpvs::bench {

/// The CPU model as /proc/cpuinfo names it.
std::string cpuModel();
/// The local time, for the report's header.
std::string now();

/// A scene of a benchmark: a short name for the tables and what kind of geometry it is.
struct BenchScene {
  std::string label;
  Scene scene;
  SceneStats stats;
  // "closed" when every triangle is in a closed part, "open" when none is, else "mixed".
  std::string kind;
};

/// Resolves a name (bunny, teapots, shouse, engine, haus, peercity, maisons: shared scenes beside the project; city or
/// city:BLOCKS[:SEED]: procedural) or a path. Returns nothing, after a line on stderr and
/// one in `notes`, when a file is absent, so that a checkout without the shared scenes
/// still benchmarks the city.
std::optional<BenchScene> openBenchScene(const std::string& spec, const std::string& program,
                                         std::vector<std::string>& notes);

/// The options every benchmark takes; a program's own Args derive from it and set the
/// defaults.
struct CommonArgs {
  std::vector<std::string> scenes{"bunny", "city", "teapots"};
  std::vector<int> log2Resolutions;
  Vec3 sunDir{0.35, -1.0, 0.25};  // oblique: no face of the city's boxes is parallel to it
  int repeat = 1;
  int threads = 0;
  bool help = false;
};

/// Parses --help, --resolutions, --scenes, --scene, --sun-dir, --repeat and --threads into
/// `common`; any other "--option value" goes to `other`, which returns false for an option
/// it does not know. InputError for a bad value or an unknown option.
void parseBenchArgs(int argc, char** argv, CommonArgs& common,
                    const std::function<bool(const std::string& option, const std::string& value)>& other);

/// main() of a benchmark: runs `run`, and turns an exception into a line on stderr and
/// exit status 2.
int benchMain(const char* program, int (*run)(int, char**), int argc, char** argv);

double parseDouble(const std::string& text, const std::string& what);
int parsePositive(const std::string& text, const std::string& what);

std::string format(const char* fmt, double v);
/// 16K, 256K, or 512 below 1K.
std::string resolutionLabel(int log2R);
std::string humanBytes(uint64_t bytes);
/// A ratio as "12.3x", "n/a" for NaN.
std::string times(double ratio);
double ratio(double num, double den);

/// Nanoseconds per lookup of a lookup object's `batch` over the points at PCF `pcf`, best
/// of three.
template <class Lookup>
double lookupNs(const Lookup& lookup, const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf) {
  std::vector<float> out;
  double best = 1e30;
  for (int r = 0; r < 3; ++r) {
    const auto start = std::chrono::steady_clock::now();
    lookup.batch(points, normals, pcf, out);
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  return best * 1e9 / double(points.size());
}

}  // namespace cpvs::bench
