#include "cpvs/scene/obj_writer.h"

#include <cstdio>

#include "cpvs/base/file.h"

namespace cpvs {

std::string objText(const Scene& scene, const std::string& comment) {
  std::string out;
  if (!comment.empty()) out += "# " + comment + "\n";
  char line[128];
  for (const Vec3& p : scene.positions) {
    std::snprintf(line, sizeof line, "v %.17g %.17g %.17g\n", p.x, p.y, p.z);
    out += line;
  }
  for (size_t i = 0; i + 2 < scene.indices.size(); i += 3) {
    std::snprintf(line, sizeof line, "f %u %u %u\n", scene.indices[i] + 1, scene.indices[i + 1] + 1,
                  scene.indices[i + 2] + 1);
    out += line;
  }
  return out;
}

void writeObj(const std::string& path, const Scene& scene, const std::string& comment) {
  const std::string text = objText(scene, comment);
  writeFileAtomic(path, std::vector<uint8_t>(text.begin(), text.end()));
}

}  // namespace cpvs
