// Every light's grid as one value: what the farm's messages, its store and the files
// describe a grid with, whatever its projection.
#pragma once

#include <cstdint>
#include <string>

#include "cpvs/base/vec3.h"
#include "cpvs/light/frame.h"

namespace cpvs {

class OrthoGrid;
class PerspectiveGrid;

/// How a grid's texel rays leave the light. The values are the contract's GridProjection.
enum class Projection : uint8_t {
  Orthographic = 0,  // the sun's: parallel rays over a box
  Perspective = 1,   // a spot light's, or a point light's cube face
};

/// "orthographic", "perspective".
const char* projectionName(Projection p);

/// A grid of either projection: the frame and resolution both share; the box of an
/// orthographic grid (OrthoGrid's fields); the apex, field, depth range and the cone its
/// texels are cut off by of a perspective one (PerspectiveGrid, BundleGrid::tanCone). The
/// other projection's fields are zero. A plain value, compared field by field: to map
/// with it, make the grid (orthoGridOf, perspectiveGridOf), which validates.
struct GridSpec {
  Projection projection = Projection::Orthographic;
  LightFrame frame;
  int log2Resolution = 0;
  // Orthographic.
  Vec3 origin;
  double u0 = 0, v0 = 0, d0 = 0, extent = 0, depthExtent = 0;
  uint32_t depthSlices = 0;  // OrthoGrid::depthSlices (0: a cubic grid)
  // Perspective.
  Vec3 position;
  double tanHalfFov = 0, near = 0, far = 0, tanCone = 0;

  uint64_t resolution() const { return uint64_t(1) << log2Resolution; }
  bool operator==(const GridSpec&) const = default;
};

GridSpec gridSpecOf(const OrthoGrid& grid);
GridSpec gridSpecOf(const PerspectiveGrid& grid, double tanCone);

/// The orthographic grid `spec` describes; InputError starting with `what` for another
/// projection or fields checkGrid refuses.
OrthoGrid orthoGridOf(const GridSpec& spec, const std::string& what);

/// The perspective grid `spec` describes; InputError starting with `what` for another
/// projection, fields the PerspectiveGrid constructor refuses or a cone that is not
/// finite and > 0.
PerspectiveGrid perspectiveGridOf(const GridSpec& spec, const std::string& what);

}  // namespace cpvs
