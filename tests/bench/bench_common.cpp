#include "bench_common.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>

#include "cpvs/base/error.h"
#include "cpvs/base/parse.h"
#include "cpvs/scene/source.h"
#include "scene_testing.h"

namespace cpvs::bench {

std::string cpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0) {
      auto colon = line.find(':');
      if (colon != std::string::npos) return line.substr(line.find_first_not_of(" \t", colon + 1));
    }
  }
  return "unknown CPU";
}

std::string now() {
  std::time_t t = std::time(nullptr);
  char buf[64];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M %Z", std::localtime(&t));
  return buf;
}

std::optional<BenchScene> openBenchScene(const std::string& spec, const std::string& program,
                                         std::vector<std::string>& notes) {
  std::string path = spec, label = spec;
  if (spec == "bunny") {
    path = testing::sharedScenesDir() + "/stanford-bunny/bunny.obj";
  } else if (spec == "teapots") {
    path = testing::sharedScenesDir() + "/assimp-testmodels/teapots.DAE";
  } else if (spec == "engine") {
    path = testing::sharedScenesDir() + "/assimp-testmodels/2CylinderEngine.glb";
  } else if (spec == "shouse") {
    path = testing::sharedScenesDir() + "/openarena/oa_shouse.obj";
  } else if (spec == "peercity") {
    path = testing::sharedScenesDir() + "/loinesg-city/city.obj";
  } else if (spec == "maisons") {
    path = testing::sharedScenesDir() + "/flightgear/zone_maisons.obj";
  } else if (spec == "haus") {
    path = testing::sharedScenesDir() + "/assimp-testmodels/AC14-FZK-Haus.ifc";
  } else if (spec == "city" || spec.starts_with("city:") || spec == "landscape" || spec.starts_with("landscape:")) {
    path.clear();
  } else {
    label = std::filesystem::path(spec).stem().string();
  }
  if (!path.empty() && !std::filesystem::is_regular_file(path)) {
    notes.push_back("skipped " + label + ": " + path + " not found");
    std::fprintf(stderr, "%s: skipping %s: %s not found\n", program.c_str(), label.c_str(), path.c_str());
    return std::nullopt;
  }
  BenchScene s;
  s.label = label;
  s.scene = openScene(path.empty() ? spec : path, &s.stats);
  s.kind = s.stats.closedTriangles == s.stats.triangles ? "closed"
           : s.stats.closedTriangles == 0                ? "open"
                                                         : "mixed";
  return s;
}

int benchMain(const char* program, int (*run)(int, char**), int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", program, e.what());
    return 2;
  }
}

void parseBenchArgs(int argc, char** argv, CommonArgs& a,
                    const std::function<bool(const std::string& option, const std::string& value)>& other) {
  for (int i = 1; i < argc; ++i) {
    const std::string opt = argv[i];
    if (opt == "--help" || opt == "-h") {
      a.help = true;
      continue;
    }
    if (i + 1 >= argc) throw InputError("missing value after " + opt + " (see --help)");
    const std::string value = argv[++i];
    if (opt == "--resolutions") {
      a.log2Resolutions.clear();
      for (const auto& r : splitList(value)) a.log2Resolutions.push_back(parseResolution(r));
      if (a.log2Resolutions.empty()) throw InputError("--resolutions: empty list");
    } else if (opt == "--scenes") {
      a.scenes = splitList(value);
      if (a.scenes.empty()) throw InputError("--scenes: empty list");
    } else if (opt == "--scene") {
      // --scene alone adds to the defaults; with --scenes it adds to that list.
      a.scenes.push_back(value);
    } else if (opt == "--sun-dir") {
      auto parts = splitList(value);
      if (parts.size() != 3) throw InputError("--sun-dir: expected X,Y,Z, got '" + value + "'");
      a.sunDir = {parseDouble(parts[0], "--sun-dir"), parseDouble(parts[1], "--sun-dir"), parseDouble(parts[2], "--sun-dir")};
    } else if (opt == "--repeat") {
      a.repeat = parsePositive(value, "--repeat");
    } else if (opt == "--threads") {
      a.threads = parsePositive(value, "--threads");
    } else if (!other(opt, value)) {
      throw InputError("unknown option: " + opt + " (see --help)");
    }
  }
}

double parseDouble(const std::string& text, const std::string& what) {
  double v = 0;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(v))
    throw InputError(what + ": '" + text + "' is not a finite number");
  return v;
}

int parsePositive(const std::string& text, const std::string& what) {
  int v = 0;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || v < 1)
    throw InputError(what + ": '" + text + "' is not a positive whole number");
  return v;
}

std::string format(const char* fmt, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

std::string resolutionLabel(int log2R) {
  return log2R >= 10 ? std::to_string(1u << (log2R - 10)) + "K" : std::to_string(1u << log2R);
}

std::string humanBytes(uint64_t bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double v = double(bytes);
  int u = 0;
  while (v >= 1024 && u < 4) v /= 1024, ++u;
  return format(u == 0 ? "%.0f" : (v < 10 ? "%.2f" : (v < 100 ? "%.1f" : "%.0f")), v) + " " + units[u];
}

std::string times(double r) { return std::isnan(r) ? "n/a" : format(r < 10 ? "%.2fx" : "%.1fx", r); }

double ratio(double num, double den) { return den > 0 ? num / den : NAN; }

}  // namespace cpvs::bench
