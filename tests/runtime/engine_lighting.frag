// How an engine uses cpvs_shadow.glsl from its own lighting shader: its own set and
// bindings, the words split across two buffers, the sun through translucent casters. Compiled by the test suite (glslc) so
// that the installed include keeps compiling outside the library's own shader.
#version 450
#extension GL_GOOGLE_include_directive : require

#define CPVS_SET 1
#define CPVS_BINDING 3
#define CPVS_WORD_BUFFERS 2
#define CPVS_TRANSLUCENT
#include "cpvs_shadow.glsl"

layout(location = 0) in vec3 worldPosition;
layout(location = 1) in vec3 worldNormal;
layout(location = 0) out vec4 color;

void main() {
  const float sun = max(dot(normalize(worldNormal), vec3(0.3, 0.9, 0.2)), 0.0);
  const vec3 lit = cpvsFilteredLight(worldPosition, worldNormal, 9u) * 0.5 + cpvsVisibility(worldPosition, worldNormal) * 0.5;
  color = vec4(vec3(0.1) + 0.9 * sun * lit, 1.0);
}
