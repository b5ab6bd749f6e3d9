#include "cpvs/light/frustum_clip.h"

#include <array>
#include <cstddef>

namespace cpvs {

void clipToFrustum(std::vector<LightPoint>& poly, std::vector<LightPoint>& scratch, double zMin, double tanHalf) {
  // Plane k keeps the points where its function is >= 0.
  const std::array<LightPoint, 5> planes{LightPoint{0, 0, 1}, LightPoint{1, 0, tanHalf}, LightPoint{-1, 0, tanHalf},
                                         LightPoint{0, 1, tanHalf}, LightPoint{0, -1, tanHalf}};
  auto side = [&](const LightPoint& q, size_t k) {
    return planes[k].a * q.a + planes[k].b * q.b + planes[k].z * q.z - (k == 0 ? zMin : 0.0);
  };
  auto before = [](const LightPoint& p, const LightPoint& q) {
    return p.a < q.a || (p.a == q.a && (p.b < q.b || (p.b == q.b && p.z < q.z)));
  };
  auto crossing = [&](const LightPoint& p, const LightPoint& q, size_t k) {
    const double fp = side(p, k), fq = side(q, k), s = fp / (fp - fq);
    return LightPoint{p.a + (q.a - p.a) * s, p.b + (q.b - p.b) * s, p.z + (q.z - p.z) * s};
  };
  for (size_t k = 0; k < planes.size() && !poly.empty(); ++k) {
    bool inside = true;
    for (const LightPoint& q : poly) inside = inside && side(q, k) >= 0;
    if (inside) continue;
    scratch.clear();
    for (size_t j = 0; j < poly.size(); ++j) {
      const LightPoint p = poly[j], q = poly[(j + 1) % poly.size()];
      const bool ip = side(p, k) >= 0, iq = side(q, k) >= 0;
      if (ip) scratch.push_back(p);
      if (ip != iq) scratch.push_back(before(p, q) ? crossing(p, q, k) : crossing(q, p, k));
    }
    poly.swap(scratch);
  }
}

}  // namespace cpvs
