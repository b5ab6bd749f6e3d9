#include "cpvs/light/grid_spec.h"

#include <cmath>

#include "cpvs/base/error.h"
#include "cpvs/base/limits.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/light/perspective_grid.h"

namespace cpvs {

const char* projectionName(Projection p) {
  switch (p) {
    case Projection::Orthographic: return "orthographic";
    case Projection::Perspective: return "perspective";
  }
  return "unknown";
}

namespace {

void checkProjection(const GridSpec& s, Projection want, const std::string& what) {
  if (s.projection != want)
    throw InputError(what + ": a " + projectionName(s.projection) + " grid, not the " + projectionName(want) +
                     " one it must be");
  // The resolution is checked where the grid is made (checkGrid, PerspectiveGrid).
}

}  // namespace

GridSpec gridSpecOf(const OrthoGrid& g) {
  GridSpec s;
  s.projection = Projection::Orthographic;
  s.frame = g.frame;
  s.log2Resolution = g.log2Resolution;
  s.origin = g.origin;
  s.u0 = g.u0, s.v0 = g.v0, s.d0 = g.d0;
  s.extent = g.extent, s.depthExtent = g.depthExtent;
  s.depthSlices = g.depthSlices;
  return s;
}

GridSpec gridSpecOf(const PerspectiveGrid& g, double tanCone) {
  GridSpec s;
  s.projection = Projection::Perspective;
  s.frame = g.frame();
  s.log2Resolution = g.log2Resolution();
  s.position = g.position();
  s.tanHalfFov = g.tanHalfFov(), s.near = g.near(), s.far = g.far();
  s.tanCone = tanCone;
  return s;
}

OrthoGrid orthoGridOf(const GridSpec& s, const std::string& what) {
  checkProjection(s, Projection::Orthographic, what);
  OrthoGrid g;
  g.frame = s.frame;
  g.log2Resolution = s.log2Resolution;
  g.origin = s.origin;
  g.u0 = s.u0, g.v0 = s.v0, g.d0 = s.d0;
  g.extent = s.extent, g.depthExtent = s.depthExtent;
  g.depthSlices = s.depthSlices;
  checkGrid(g, what);
  return g;
}

PerspectiveGrid perspectiveGridOf(const GridSpec& s, const std::string& what) {
  checkProjection(s, Projection::Perspective, what);
  if (!(s.tanCone > 0) || !std::isfinite(s.tanCone)) throw InputError(what + ": the cone's tangent must be finite and > 0");
  try {
    return PerspectiveGrid(s.position, s.frame, s.tanHalfFov, s.near, s.far, s.log2Resolution);
  } catch (const InputError& e) {
    throw InputError(what + ": " + e.what());
  }
}

}  // namespace cpvs
