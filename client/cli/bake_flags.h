// The flags that describe a bake, shared by `bake`, `submit` and `accuracy`: the light,
// and the bake options with the names of bake/options.h.
#pragma once

#include <CLI/CLI.hpp>

#include <cmath>
#include <string>

#include "cpvs/bake/options.h"
#include "cpvs/light/frame.h"

namespace cpvs::cli {

/// --sun-dir, or --sun-elevation with --sun-azimuth.
struct SunFlags {
  std::string dir;
  double elevation = NAN, azimuth = NAN;
};
void addSunFlags(CLI::App* c, SunFlags& sun);

/// --closed, --exit, --cull, --compress, --undefined, --renderer, --tile-size.
struct OptionFlags {
  std::string closed = optionName(ClosedMode::Auto), exit = optionName(ExitMode::Exact), cull = "on",
              compress = optionName(CompressMode::TopDown), undefinedRule = optionName(UndefinedRule::New),
              renderer = optionName(BakeOptions{}.renderer);
  int tileSize = 1 << kDefaultLog2TileSize;
};
/// `tileHelp` says what the tile size means to this command.
void addOptionFlags(CLI::App* c, OptionFlags& options, const std::string& tileHelp);
/// The bake options the flags name; InputError naming the flag otherwise.
BakeOptions optionsOf(const OptionFlags& flags);

}  // namespace cpvs::cli
