// openScene: one name space for scenes, files and generated ones alike.
#include <charconv>
#include <optional>
#include <string>

#include "cpvs/scene/source.h"

#include "cpvs/base/error.h"
#include "cpvs/scene/import.h"
#include "cpvs/scene/isolated_import.h"
#include "cpvs/scene/procedural_city.h"
#include "cpvs/scene/procedural_landscape.h"

namespace cpvs {

namespace {

int parseCityNumber(const std::string& spec, std::string_view part, const char* what) {
  long long value = 0;
  auto [end, ec] = std::from_chars(part.data(), part.data() + part.size(), value);
  if (ec != std::errc() || end != part.data() + part.size() || value < 0 || value > 0xFFFFFFFFll)
    throw InputError("scene '" + spec + "': " + what + " '" + std::string(part) + "' is not a whole number");
  return int(value);
}

// Set once by the program before any import (isolateSceneImports).
std::optional<ImportLimits> isolation;

}  // namespace

void isolateSceneImports(const ImportLimits& limits) { isolation = limits; }

Scene openScene(const std::string& spec, SceneStats* stats) {
  const bool city = spec == "city" || spec.starts_with("city:");
  const bool landscape = spec == "landscape" || spec.starts_with("landscape:");
  if (!city && !landscape) return isolation ? importIsolated(spec, *isolation, stats, nullptr) : loadScene(spec, stats);
  // NAME[:FIRST[:SEED]]: blocks for the city, cells a side for the landscape.
  int first = city ? 12 : 256;
  uint32_t seed = 1;
  const size_t name = city ? 4 : 9;
  if (spec.size() > name) {
    std::string_view rest(spec);
    rest.remove_prefix(name + 1);
    size_t colon = rest.find(':');
    first = parseCityNumber(spec, rest.substr(0, colon), city ? "block count" : "size");
    if (colon != std::string_view::npos) seed = uint32_t(parseCityNumber(spec, rest.substr(colon + 1), "seed"));
  }
  Scene scene = city ? makeProceduralCity(first, seed) : makeFractalLandscape(first, seed);
  // The generator finalizes already; finalizing again only recounts.
  SceneStats s = finalizeScene(scene);
  if (stats) *stats = s;
  return scene;
}

}  // namespace cpvs
