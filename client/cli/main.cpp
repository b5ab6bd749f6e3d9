// `cpvs`: bake, inspect, query, verify and render compact precomputed voxelized shadows,
// in this process or on a bake farm (submit, jobs, watch, cancel, download).
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <string>

#include "commands.h"
#include "cpvs/base/vec3.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/error.h"
#include "cpvs/runtime/runtime.h"
#include "cpvs/scene/isolated_import.h"

namespace {

// Every scene file is imported in a child process (cpvs-import, beside this program),
// limited in memory and time (CPVS_IMPORT_MEMORY_MB, CPVS_IMPORT_SECONDS): a file that
// crashes or hangs assimp costs a clear error, never this process.
void isolateImports() {
  cpvs::ImportLimits limits;
  limits.helper = cpvs::importProgram();
  if (limits.helper.empty()) return;  // no /proc: imported in this process
  limits.selfContained = false;
  auto positive = [](const char* name, double fallback) {
    const char* text = std::getenv(name);
    if (!text || !*text) return fallback;
    char* end = nullptr;
    const double v = std::strtod(text, &end);
    if (*end != '\0' || !(v > 0)) throw cpvs::InputError(std::string(name) + "='" + text + "': a positive number");
    return v;
  };
  limits.memoryBytes = uint64_t(positive("CPVS_IMPORT_MEMORY_MB", double(limits.memoryBytes >> 20))) << 20;
  limits.seconds = positive("CPVS_IMPORT_SECONDS", limits.seconds);
  cpvs::isolateSceneImports(limits);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "cpvs: compact precomputed voxelized shadows.\n"
      "Bakes the sun's binary visibility of every voxel of a scene into a small DAG, and queries it.\n"
      "Bakes run in this process (bake) or on a bake farm (submit, jobs, watch, cancel, download)."};
  app.require_subcommand(1);
  int status = 0;
  cpvs::cli::addBakeCommand(app, status);
  cpvs::cli::addInspectCommand(app, status);
  cpvs::cli::addPlanCommand(app, status);
  cpvs::cli::addQueryCommand(app, status);
  cpvs::cli::addVerifyCommand(app, status);
  cpvs::cli::addRenderCommand(app, status);
  cpvs::cli::addContactSheetCommand(app, status);
  cpvs::cli::addAccuracyCommand(app, status);
  cpvs::cli::addSunCommand(app, status);
  cpvs::cli::addSubmitCommand(app, status);
  cpvs::cli::addJobsCommand(app, status);
  cpvs::cli::addWatchCommand(app, status);
  cpvs::cli::addCancelCommand(app, status);
  cpvs::cli::addDownloadCommand(app, status);
  cpvs::cli::addTrackCommand(app, status);
  cpvs::cli::addSubscribeCommand(app, status);
  spdlog::set_pattern("[%H:%M:%S] %v");
  try {
    isolateImports();
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help prints and exits 0; every malformed command line exits 2 like other bad input.
    return app.exit(e) == 0 ? 0 : 2;
  } catch (const cpvs::InputError& e) {
    std::fprintf(stderr, "cpvs: %s\n", e.what());
    return 2;
  } catch (const cpvs::runtime::RuntimeError& e) {
    using cpvs::runtime::Status;
    const Status s = e.status();
    if (s == Status::NoVulkan || s == Status::NoDevice || s == Status::DeviceLost) {
      std::fprintf(stderr, "cpvs: --gpu: %s (leave out --gpu to look up on the CPU)\n", e.what());
      return 5;
    }
    std::fprintf(stderr, "cpvs: %s\n", e.what());
    return s == Status::InvalidArgument || s == Status::FileError || s == Status::CorruptArtifact ? 2 : 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cpvs: internal error: %s\n", e.what());
    return 3;
  }
  return status;
}
