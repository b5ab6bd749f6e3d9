// The query path alone: opens a .cpvs and answers lookups, linked against only the query,
// io, dag, light and base libraries (tests/CMakeLists.txt refuses to configure if Embree,
// assimp, OpenEXR or PNG reach its link, and query_path_test checks the binary too).
//   query_path FILE.cpvs PCF < POINTS        one row x,y,z[,nx,ny,nz] per line
// prints what `cpvs query FILE.cpvs --points POINTS --pcf PCF` prints.
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "cpvs/base/error.h"
#include "cpvs/base/parse.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/query/shadow_query.h"

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: query_path FILE.cpvs PCF < POINTS\n");
    return 2;
  }
  try {
    cpvs::CpvsArtifact art = cpvs::readCpvs(argv[1]);
    const cpvs::ShadowQuery query(art.grid, std::move(art.packed));
    std::vector<cpvs::Vec3> points, normals;
    std::string line;
    for (int row = 1; std::getline(std::cin, line); ++row) {
      if (line.empty()) continue;
      const auto v = cpvs::parseNumbers(line, "line " + std::to_string(row));
      if (v.size() != 3 && v.size() != 6) throw cpvs::InputError("line " + std::to_string(row) + ": 3 or 6 numbers");
      points.push_back({v[0], v[1], v[2]});
      normals.push_back(v.size() == 6 ? cpvs::Vec3{v[3], v[4], v[5]} : cpvs::Vec3{});
    }
    std::vector<float> out;
    query.batch(points, normals, std::stoi(argv[2]), out);
    std::printf("x,y,z,visibility\n");
    for (size_t i = 0; i < points.size(); ++i)
      std::printf("%.9g,%.9g,%.9g,%.6g\n", points[i].x, points[i].y, points[i].z, out[i]);
    return 0;
  } catch (const cpvs::InputError& e) {
    std::fprintf(stderr, "query_path: %s\n", e.what());
    return 2;
  }
}
