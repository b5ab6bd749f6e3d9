// `cpvs-import FILE [--references]`: the child process that imports one scene file for
// `cpvs` and `cpvs-server` (cpvs/scene/isolated_import.h), in the import
// sandbox, writing the mesh to stdout. A program of its own so that a child starts in a
// few milliseconds: it loads the importer's libraries only, not gRPC, Embree or Vulkan.
#include <cstdio>
#include <string>

#include "cpvs/scene/isolated_import.h"

int main(int argc, char** argv) {
  const bool help = argc == 2 && (std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h");
  if (help || argc < 2 || argc > 3 || (argc == 3 && std::string(argv[2]) != "--references")) {
    std::fprintf(help ? stdout : stderr,
                 "Usage: cpvs-import FILE [--references]\n"
                 "The scene import child of cpvs and cpvs-server: imports FILE (with the files it refers to, with "
                 "--references) in the import sandbox and writes its mesh to standard output. They start it; it is "
                 "not for people.\n");
    return help ? 0 : 2;
  }
  return cpvs::runImportHelper(argv[1], argc == 2);
}
