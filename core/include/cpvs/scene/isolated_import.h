// Scene files are imported outside the process that wants them: assimp is not robust
// against hostile or broken files, so each import runs in a child process (`cpvs-import`,
// installed beside cpvs-server for uploads and cpvs for local bakes) with its address
// space, CPU time and file writes limited, a wall-clock timeout and a seccomp filter. What comes back is a scene mesh file (cpvs/scene/mesh_file.h), checked like any
// untrusted input. A crash, a hang or a memory blow-up of the importer costs that file only.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cpvs/scene/scene.h"

namespace cpvs {

struct ImportLimits {
  /// The program run as `HELPER FILE [--references]` (cpvs-import, importProgram());
  /// empty: import in this process, not isolated (tests and tools that embed a coordinator).
  std::string helper;
  uint64_t memoryBytes = uint64_t(8) << 30;  // address space of the importer
  double seconds = 600;                      // wall clock (and CPU time) of one import
  /// Open the named file only (uploads: ImportOptions::selfContained); false: the files
  /// it refers to as well (an OBJ's materials), as a local bake reads them.
  bool selfContained = true;
};

/// Imports `path`: the scene and its statistics, and the mesh file's bytes in
/// `meshBytes`. InputError when the file is the problem (it does not import, refers to
/// other files, crashes the importer, needs more memory or time than the limits);
/// std::runtime_error when the importer cannot be run at all.
Scene importIsolated(const std::string& path, const ImportLimits& limits, SceneStats* stats,
                     std::vector<uint8_t>* meshBytes);

/// cpvs-import beside the running program (the folder of /proc/self/exe), where a build
/// and an install put it; empty when /proc cannot say where this program is.
std::string importProgram();
/// importProgram(), which `program` (a farm process) cannot serve without: InputError,
/// naming it, when it is not there to run.
std::string requiredImportProgram(const std::string& program);

/// The child's side (cpvs-import's main: `FILE [--references]`): imports FILE (self-contained
/// unless `selfContained` is false) and writes its mesh file to standard output. Exit status 0, 2 (the file does not import; the reason on standard error), or
/// 3 (anything else, out of memory included). CPVS_FAILPOINT=import-crash, import-hang
/// or import-hog (or POINT:TEXT, for a path holding TEXT) makes it crash, hang or
/// allocate without bound, for the tests.
int runImportHelper(const std::string& path, bool selfContained = true);

/// From now on openScene imports files through importIsolated with `limits` (what a
/// program that must survive any file calls once, first thing: the command line).
void isolateSceneImports(const ImportLimits& limits);

}  // namespace cpvs
