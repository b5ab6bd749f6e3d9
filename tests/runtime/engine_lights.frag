// How an engine shades the sun and a light bundle's local lights in one lighting shader
// with cpvs_shadow.glsl: both artifacts bound side by side in its own set, the sun's
// words in one buffer and the bundle's pool split across two; the sun's light also
// and every lamp's blocked by what moves (the dynamic casters' trees after them: the
// sun's at binding 9, the lamps' headers and nodes at 10 and 11; the sun's translucent
// casters' tree and transmittance at 12 and 13). Compiled by the test suite
// (glslc) so that the installed include keeps compiling outside the library's shaders.
#version 450
#extension GL_GOOGLE_include_directive : require

#define CPVS_SET 2
#define CPVS_BINDING 0
#define CPVS_LIGHTS
#define CPVS_LIGHT_BINDING 4
#define CPVS_LIGHT_WORD_BUFFERS 2
#define CPVS_CASTERS
#define CPVS_LIGHT_CASTERS
#define CPVS_TRANSLUCENT
#include "cpvs_shadow.glsl"

layout(location = 0) in vec3 worldPosition;
layout(location = 1) in vec3 worldNormal;
layout(location = 0) out vec4 color;

void main() {
  const vec3 n = normalize(worldNormal);
  vec3 c = vec3(0.9, 0.85, 0.7) * max(dot(n, vec3(0.3, 0.9, 0.2)), 0.0) * cpvsFilteredWithCasters(worldPosition, worldNormal, 5u);
  vec3 throughGlass;
  cpvsTranslucentTransmittance(dvec3(worldPosition), dvec3(worldNormal), throughGlass);
  c *= throughGlass;
  for (uint i = 0u; i < cpvsLightCount(); ++i) {
    const CpvsLight l = cpvsLights[i];
    const vec3 toLight = vec3(l.position[0], l.position[1], l.position[2]) - worldPosition;
    const float d = length(toLight);
    if (d > l.range) continue;
    const vec3 w = toLight / d;
    if (dot(-w, vec3(l.direction[0], l.direction[1], l.direction[2])) < l.cosCone) continue;
    const float v = cpvsLightVisibilityWithCasters(i, worldPosition, worldNormal, 9u);
    c += vec3(l.colour[0], l.colour[1], l.colour[2]) * (l.intensity * v * max(dot(n, w), 0.0) / max(d * d, 1.0));
  }
  color = vec4(c, 1.0);
}
