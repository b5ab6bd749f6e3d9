// Filling one lane of an Embree ray packet, and the front-face rule. Private to raytrace.
#pragma once

#include <embree3/rtcore.h>

#include "cpvs/base/vec3.h"

namespace cpvs {

/// Lane l of `rh`: a ray from `origin` along `dir` up to `tfar`, no hit yet.
inline void setPacketRay(RTCRayHit8& rh, int l, const Vec3& origin, const Vec3& dir, float tfar) {
  rh.ray.org_x[l] = float(origin.x);
  rh.ray.org_y[l] = float(origin.y);
  rh.ray.org_z[l] = float(origin.z);
  rh.ray.dir_x[l] = float(dir.x);
  rh.ray.dir_y[l] = float(dir.y);
  rh.ray.dir_z[l] = float(dir.z);
  rh.ray.tnear[l] = 0.0f;
  rh.ray.tfar[l] = tfar;
  rh.ray.time[l] = 0.0f;
  rh.ray.mask[l] = 0xFFFFFFFFu;
  rh.ray.id[l] = unsigned(l);
  rh.ray.flags[l] = 0;
  rh.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
}

/// A hit is on the surface's front side when the geometric normal (Embree's Ng, the
/// unnormalized cross(v1 - v0, v2 - v0)) faces against the ray: ng = dot(Ng, dir) < 0.
inline bool frontFacing(float ng) { return ng < 0; }

}  // namespace cpvs
