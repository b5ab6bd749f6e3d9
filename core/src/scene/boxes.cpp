#include "cpvs/scene/boxes.h"

namespace cpvs {

void appendBox(Scene& scene, const Vec3& lo, const Vec3& hi) {
  const uint32_t base = static_cast<uint32_t>(scene.positions.size());
  // Corner i has x from bit 0, y from bit 1, z from bit 2.
  for (int i = 0; i < 8; ++i) scene.positions.push_back({(i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z});
  // Each face as a quad, counter-clockwise seen from outside.
  static constexpr int kFaces[6][4] = {
      {0, 4, 6, 2},  // -x
      {1, 3, 7, 5},  // +x
      {0, 1, 5, 4},  // -y
      {2, 6, 7, 3},  // +y
      {0, 2, 3, 1},  // -z
      {4, 5, 7, 6},  // +z
  };
  for (const auto& f : kFaces)
    for (int c : {f[0], f[1], f[2], f[0], f[2], f[3]}) scene.indices.push_back(base + uint32_t(c));
}

}  // namespace cpvs
