#include "bundle_text.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "bake_flags.h"
#include "cli_util.h"

namespace cpvs::cli {

uint64_t bundleShadowMapBytes(const LightBundle& b) {
  uint64_t bytes = 0;
  for (const BundleGrid& g : b.grids) bytes += 2 * g.grid.resolution() * g.grid.resolution();
  return bytes;
}

std::string bundleTable(const LightBundle& b) {
  std::ostringstream o;
  char line[512];
  std::snprintf(line, sizeof line, "  %-5s %-18s %-5s %-32s %7s %10s %10s %12s\n", "light", "name", "kind", "position",
                "grids", "resolution", "near..far", "bytes");
  o << line;
  uint64_t separate = 0;
  for (size_t i = 0; i < b.lights.size(); ++i) {
    const BundleLight& bl = b.lights[i];
    const BundleGrid& g = b.grids[bl.firstGrid];
    const uint64_t bytes = b.lightBytes(i);
    separate += bytes;
    char pos[96], range[64];
    std::snprintf(pos, sizeof pos, "(%.4g, %.4g, %.4g)", bl.light.position.x, bl.light.position.y, bl.light.position.z);
    std::snprintf(range, sizeof range, "%.3g..%.3g", g.grid.near(), g.grid.far());
    std::snprintf(line, sizeof line, "  %-5zu %-18s %-5s %-32s %7u %10llu %10s %12s\n", i,
                  loggable(bl.light.name, 18).c_str(), lightKindName(bl.light.kind), pos, bl.gridCount,
                  static_cast<unsigned long long>(g.grid.resolution()), range, humanBytes(bytes).c_str());
    o << line;
  }
  const uint64_t maps = bundleShadowMapBytes(b);
  std::snprintf(line, sizeof line,
                "\n  %zu lights, %zu grids: the shared pool holds %s, separate DAGs %s (%.2fx); 16-bit shadow maps "
                "of the same grids %s (%.1fx the pool)\n",
                b.lights.size(), b.grids.size(), humanBytes(b.poolBytes).c_str(), humanBytes(separate).c_str(),
                double(separate) / double(std::max<uint64_t>(1, b.poolBytes)), humanBytes(maps).c_str(),
                double(maps) / double(std::max<uint64_t>(1, b.poolBytes)));
  o << line << "  receivers: " << receiversText(b.options, b.receiverHash) << "\n";
  return o.str();
}

std::string lightPlanTable(const LightBundle& b, const std::vector<double>& closest, double footprint,
                           const ReceiverDeclaration& receivers) {
  std::ostringstream o;
  char line[512];
  std::snprintf(line, sizeof line, "%zu local light%s, %zu grid%s; each grid's resolution keeps its texels at most %.4g wide "
                "at its far end (--footprint)\n\n", b.lights.size(), b.lights.size() == 1 ? "" : "s", b.grids.size(),
                b.grids.size() == 1 ? "" : "s", footprint);
  o << line;
  std::snprintf(line, sizeof line, "  %-5s %-18s %-5s %-32s %5s %10s %18s %10s %10s\n", "light", "name", "kind", "position",
                "grids", "resolution", "near..far", "closest", "texel@far");
  o << line;
  for (size_t i = 0; i < b.lights.size(); ++i) {
    const BundleLight& bl = b.lights[i];
    uint64_t R = 0;
    double near = INFINITY, far = 0, nearest = INFINITY, texel = 0;
    for (uint32_t k = bl.firstGrid; k < bl.firstGrid + bl.gridCount; ++k) {
      const PerspectiveGrid& g = b.grids[k].grid;
      R = std::max(R, g.resolution());
      near = std::min(near, g.near()), far = std::max(far, g.far());
      if (k < closest.size()) nearest = std::min(nearest, closest[k]);
      texel = std::max(texel, 2 * g.far() * g.tanHalfFov() / double(g.resolution()));
    }
    char pos[96], range[64], seen[32];
    std::snprintf(pos, sizeof pos, "(%.4g, %.4g, %.4g)", bl.light.position.x, bl.light.position.y, bl.light.position.z);
    std::snprintf(range, sizeof range, "%.3g..%.3g", near, far);
    if (std::isfinite(nearest)) std::snprintf(seen, sizeof seen, "%.3g", nearest);
    else std::snprintf(seen, sizeof seen, "nothing");
    std::snprintf(line, sizeof line, "  %-5zu %-18s %-5s %-32s %5u %10llu %18s %10s %10.3g\n", i,
                  loggable(bl.light.name, 18).c_str(), lightKindName(bl.light.kind), pos, bl.gridCount,
                  static_cast<unsigned long long>(R), range, seen, texel);
    o << line;
  }
  std::snprintf(line, sizeof line, "\n  16-bit shadow maps of these grids would hold %s; the bake shares one node pool\n",
                humanBytes(bundleShadowMapBytes(b)).c_str());
  o << line << "  receivers: " << receiversText(b.options, receiverHash(receivers)) << "\n";
  return o.str();
}

std::string bundleJsonFields(const LightBundle& b) {
  std::ostringstream o;
  uint64_t separate = 0;
  o << "\"lights\": [";
  for (size_t i = 0; i < b.lights.size(); ++i) {
    const BundleLight& bl = b.lights[i];
    const Light& l = bl.light;
    separate += b.lightBytes(i);
    o << (i ? ",\n    " : "\n    ") << "{\"index\": " << i << ", \"name\": " << jsonString(l.name)
      << ", \"kind\": " << jsonString(lightKindName(l.kind)) << ", \"position\": [" << jsonNumber(l.position.x) << ", "
      << jsonNumber(l.position.y) << ", " << jsonNumber(l.position.z) << "]";
    if (l.kind == LightKind::Spot)
      o << ", \"direction\": [" << jsonNumber(l.direction.x) << ", " << jsonNumber(l.direction.y) << ", "
        << jsonNumber(l.direction.z) << "], \"cone_deg\": " << jsonNumber(l.coneDeg);
    o << ", \"range\": " << jsonNumber(l.range) << ", \"colour\": [" << jsonNumber(l.colour.x) << ", "
      << jsonNumber(l.colour.y) << ", " << jsonNumber(l.colour.z) << "], \"intensity\": " << jsonNumber(l.intensity)
      << ", \"grids\": [";
    for (uint32_t k = bl.firstGrid; k < bl.firstGrid + bl.gridCount; ++k) {
      const BundleGrid& g = b.grids[k];
      o << (k > bl.firstGrid ? ", " : "") << "{\"resolution\": " << g.grid.resolution() << ", \"near\": "
        << jsonNumber(g.grid.near()) << ", \"far\": " << jsonNumber(g.grid.far()) << ", \"tan_half_fov\": "
        << jsonNumber(g.grid.tanHalfFov()) << ", \"pointer_grid_levels\": " << b.dag(k).header().gridLevels
        << ", \"bytes\": " << g.bytes << "}";
    }
    o << "], \"bytes\": " << b.lightBytes(i) << "}";
  }
  o << "\n  ],\n  \"grids\": " << b.grids.size() << ",\n  \"pool_bytes\": " << b.poolBytes
    << ",\n  \"separate_bytes\": " << separate << ",\n  \"shadow_map_bytes\": " << bundleShadowMapBytes(b)
    << ",\n  \"receivers\": " << receiversJson(b.options, b.receiverHash);
  return o.str();
}

}  // namespace cpvs::cli
