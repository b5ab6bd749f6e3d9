// The TOP tree of a scene's translucent casters (glass, water, leaves on cards), which the
// bake leaves out of the CPVS: what darkens the light behind them (seed 003 §3.4).
#pragma once

#include "cpvs/psv/top_tree.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

/// The tree of the scene's translucent meshes (translucentCasters) for one light, each
/// frustum with its mesh's transmittance: built without front-face culling (light crosses
/// both sides of a closed pane), for queries anywhere in the scene's bounds (and the
/// light's position), with the default seed. An empty tree when nothing is translucent.
TopTree translucentTree(const Scene& scene, const PsvLight& light);

}  // namespace cpvs
