#include "bake_flags.h"

#include <algorithm>
#include <vector>

namespace cpvs::cli {

namespace {

template <class Option>
std::vector<std::string> namesOf() {
  const auto& names = OptionNames<Option>::kNames;
  return {names.begin(), names.end()};
}

}  // namespace

void addSunFlags(CLI::App* c, SunFlags& sun) {
  c->add_option("--sun-dir", sun.dir, "Light direction X,Y,Z, from the sun into the scene (any side)");
  c->add_option("--sun-elevation", sun.elevation, "Sun elevation above the horizon in degrees (0..90, Y up)");
  c->add_option("--sun-azimuth", sun.azimuth, "Sun azimuth in degrees (0 = towards +Z, 90 = towards +X)");
}

void addOptionFlags(CLI::App* c, OptionFlags& o, const std::string& tileHelp) {
  c->add_option("--closed", o.closed, "Closed-geometry interiors: auto (watertight parts), on (all), off (none)")
      ->check(CLI::IsMember(namesOf<ClosedMode>()))->capture_default_str();
  c->add_option("--exit", o.exit, "Exit depth: exact (face counting) or approx (first back face)")
      ->check(CLI::IsMember(namesOf<ExitMode>()))->capture_default_str();
  c->add_option("--cull", o.cull, "Cull identical nodes during insertion (§3.2)")
      ->check(CLI::IsMember({"on", "off"}))->capture_default_str();
  c->add_option("--compress", o.compress, "Compression: topdown (§4.2), bottomup (§4.1), none (as inserted)")
      ->check(CLI::IsMember(namesOf<CompressMode>()))->capture_default_str();
  c->add_option("--undefined", o.undefinedRule, "Undefined voxels: new (§3.4 masks) or old (mixed -> shadowed)")
      ->check(CLI::IsMember(namesOf<UndefinedRule>()))->capture_default_str();
  c->add_option("--renderer", o.renderer,
                "Depth maps: raster (exact rasterization, fast) or embree (a ray per texel); they differ only on "
                "texels whose ray grazes an edge")
      ->check(CLI::IsMember(namesOf<Renderer>()))->capture_default_str();
  c->add_option("--tile-size", o.tileSize, tileHelp)->capture_default_str();
}

BakeOptions optionsOf(const OptionFlags& f) {
  BakeOptions o;
  o.closed = parseOption<ClosedMode>(f.closed, "--closed");
  o.exit = parseOption<ExitMode>(f.exit, "--exit");
  o.cull = f.cull == "on";
  o.compress = parseOption<CompressMode>(f.compress, "--compress");
  o.undefinedRule = parseOption<UndefinedRule>(f.undefinedRule, "--undefined");
  o.renderer = parseOption<Renderer>(f.renderer, "--renderer");
  o.log2TileSize = log2TileSizeOf(uint64_t(std::max(f.tileSize, 0)), "--tile-size");
  return o;
}

}  // namespace cpvs::cli
