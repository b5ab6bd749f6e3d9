// openScene: one name space for scenes, files and generated ones alike.
#include <charconv>
#include <string>

#include "cpvs/scene/source.h"

#include "cpvs/base/error.h"
#include "cpvs/scene/import.h"
#include "cpvs/scene/procedural_city.h"

namespace cpvs {

namespace {

int parseCityNumber(const std::string& spec, std::string_view part, const char* what) {
  long long value = 0;
  auto [end, ec] = std::from_chars(part.data(), part.data() + part.size(), value);
  if (ec != std::errc() || end != part.data() + part.size() || value < 0 || value > 0xFFFFFFFFll)
    throw InputError("scene '" + spec + "': " + what + " '" + std::string(part) + "' is not a whole number");
  return int(value);
}

}  // namespace

Scene openScene(const std::string& spec, SceneStats* stats) {
  if (spec != "city" && !spec.starts_with("city:")) return loadScene(spec, stats);
  int blocks = 12;
  uint32_t seed = 1;
  if (spec.size() > 5) {
    std::string_view rest(spec);
    rest.remove_prefix(5);
    size_t colon = rest.find(':');
    blocks = parseCityNumber(spec, rest.substr(0, colon), "block count");
    if (colon != std::string_view::npos) seed = uint32_t(parseCityNumber(spec, rest.substr(colon + 1), "seed"));
  }
  Scene scene = makeProceduralCity(blocks, seed);
  // The generator finalizes already; finalizing again only recounts.
  SceneStats s = finalizeScene(scene);
  if (stats) *stats = s;
  return scene;
}

}  // namespace cpvs
