#include "cpvs/light/gpu_grid.h"

#include "cpvs/light/ortho_grid.h"
#include "cpvs/light/perspective_grid.h"

namespace cpvs {

GpuGrid gpuGridOf(const GridSpec& spec, const std::string& what, uint32_t headerWord, uint32_t firstBoundary,
                  uint32_t light) {
  GpuGrid g{};
  g.projection = uint32_t(spec.projection);
  g.log2Resolution = uint32_t(spec.log2Resolution);
  g.headerWord = headerWord;
  g.firstBoundary = firstBoundary;
  g.light = light;
  if (spec.projection == Projection::Orthographic) {
    const OrthoGrid o = orthoGridOf(spec, what);
    g.mapping = o.lookupMapping();
    g.depthShift = uint32_t(o.depthShift());
    return g;
  }
  const PerspectiveGrid p = perspectiveGridOf(spec, what);
  const LightFrame& f = p.frame();
  g.mapping = {{p.position().x, p.position().y, p.position().z}, {f.u.x, f.u.y, f.u.z}, {f.v.x, f.v.y, f.v.z},
               {f.dir.x, f.dir.y, f.dir.z}, {0, 0, 0}, {0, 0, 0}};
  g.tanHalfFov = p.tanHalfFov();
  g.tanCone = spec.tanCone;
  g.near = p.near();
  g.far = p.far();
  g.logRatio = p.logRatio();
  return g;
}

}  // namespace cpvs
