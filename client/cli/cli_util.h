// Parsing and printing helpers shared by the subcommands.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/base/parse.h"
#include "cpvs/light/frame.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/base/vec3.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/text.h"
#include "cpvs/base/error.h"
#include "cpvs/base/progress.h"

namespace cpvs::cli {

/// The light of --sun-dir (any side) or --sun-elevation/--sun-azimuth (azimuth 0 when
/// not given; NaN = not given), with an error naming the flags when both or neither are.
LightFrame lightFromFlags(const std::string& sunDir, double elevation, double azimuth);

/// Minimal JSON writing: escaped strings, finite numbers.
using cpvs::jsonNumber;
using cpvs::jsonString;

/// "1.23 MB" style.
std::string humanBytes(uint64_t bytes);

/// "12.3s", "4m05s", "2h10m".
std::string formatSeconds(double seconds);

/// A progress display: a bar with stage, counts and ETA on a terminal, plain log lines
/// (at most every 10 % or 5 s) otherwise.
class ProgressDisplay {
 public:
  explicit ProgressDisplay(bool enabled);
  ~ProgressDisplay();
  /// Draws `p`; its ETA is p.secondsLeft when the work gave one, else done/total's
  /// extrapolation of the time so far.
  bool update(const Progress& p);
  void finish();

 private:
  bool enabled_, tty_;
  double start_, lastLog_ = -1;
  int lastPercent_ = -1;
  bool drawn_ = false;
};

}  // namespace cpvs::cli

#include "cpvs/io/cpvs_file.h"
#include "cpvs/scene/source.h"

namespace cpvs::cli {

/// Opens the scene an artifact was baked from and checks, by content hash, that it is
/// the same geometry: verifying or rendering against another scene would compare
/// shadows of different worlds. InputError otherwise.
Scene openMatchingScene(const std::string& spec, const CpvsArtifact& artifact);
/// The same for any file that recorded the scene's hash (a light bundle).
Scene openMatchingScene(const std::string& spec, const Hash128& sceneHash);

/// Light along segments (`query --segment`, `render --fog`) reads the grid in the air:
/// InputError for an artifact baked for surfaces only, whose voxels off them are free;
/// a note for one baked for declared volumes, which answers only inside them.
void checkGridInTheAir(const CpvsArtifact& artifact, const std::string& file, const std::string& flag);

}  // namespace cpvs::cli
