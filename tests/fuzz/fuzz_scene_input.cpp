// libFuzzer target: the scene inputs the project itself interprets, after whatever an
// importer hands over: arbitrary positions (NaN, infinities, huge and tiny values) and
// indices, the closed-part classifier, the content hash, light frames from arbitrary
// vectors and angles, grid fitting, and resolution strings.
#include <cstdint>
#include <cstring>
#include <string>

#include "cpvs/base/error.h"
#include "cpvs/base/parse.h"
#include "cpvs/light/frame.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/scene/scene.h"

namespace {

struct Input {
  const uint8_t* p;
  size_t n;
  template <class T>
  bool take(T& v) {
    if (n < sizeof(T)) return false;
    std::memcpy(&v, p, sizeof(T));
    p += sizeof(T);
    n -= sizeof(T);
    return true;
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Input in{data, size};
  uint8_t mode = 0;
  if (!in.take(mode)) return 0;
  if (mode % 2 == 0) {
    // A resolution string.
    try {
      (void)cpvs::parseResolution(std::string(reinterpret_cast<const char*>(in.p), std::min<size_t>(in.n, 32)));
    } catch (const cpvs::InputError&) {
    }
    return 0;
  }
  uint8_t vertices = 0, triangles = 0;
  if (!in.take(vertices) || !in.take(triangles)) return 0;
  cpvs::Scene scene;
  scene.name = "fuzz";
  for (int i = 0; i < vertices % 64; ++i) {
    float xyz[3];
    if (!in.take(xyz)) break;
    scene.positions.push_back({xyz[0], xyz[1], xyz[2]});
  }
  for (int t = 0; t < triangles % 96; ++t) {
    uint8_t idx[3];
    if (!in.take(idx)) break;
    for (uint8_t i : idx) scene.indices.push_back(i);
  }
  double dir[3] = {0.3, -1, 0.2}, angles[2] = {30, 40};
  in.take(dir);
  in.take(angles);
  try {
    cpvs::finalizeScene(scene);
    (void)cpvs::sceneHash(scene);
    cpvs::LightFrame f = cpvs::LightFrame::fromDirection({dir[0], dir[1], dir[2]});
    (void)cpvs::LightFrame::fromElevationAzimuth(angles[0], angles[1]);
    cpvs::OrthoGrid g = cpvs::makeGrid(scene, f, 3 + int(mode / 2) % 18);
    (void)g.voxelFromWorld({1, 2, 3});
  } catch (const cpvs::InputError&) {
  }
  return 0;
}
