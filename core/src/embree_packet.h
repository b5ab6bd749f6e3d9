// Filling one lane of an Embree ray packet, as every packet renderer here does.
#pragma once

#include <embree3/rtcore.h>

#include "cpvs/types.h"

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

}  // namespace cpvs
