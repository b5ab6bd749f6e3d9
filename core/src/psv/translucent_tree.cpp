#include "cpvs/psv/translucent_tree.h"

namespace cpvs {

TopTree translucentTree(const Scene& scene, const PsvLight& light) {
  const TranslucentCasters casters = translucentCasters(scene);
  TopTreeOptions options;
  options.frontFaceCulling = false;
  sceneBounds(scene, options.domainLo, options.domainHi);
  if (!light.directional) {
    options.domainLo = min(options.domainLo, light.vector);
    options.domainHi = max(options.domainHi, light.vector);
  }
  TopTree tree = TopTree::build(casters.positions, casters.indices, {}, light, options);
  tree.setTransmittance(casters.transmittance);
  return tree;
}

}  // namespace cpvs
