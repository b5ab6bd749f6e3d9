// A grid as a GPU reads it: the one record (cpvs_shadow.glsl's CpvsGrid) that the sun's
// lookups and a light bundle's read alike, made from the grid's one description.
#pragma once

#include <cstdint>
#include <string>

#include "cpvs/light/grid_spec.h"
#include "cpvs/light/lookup_mapping.h"

namespace cpvs {

/// 208 bytes of doubles and 32-bit words, laid out alike in std140 and std430 (no arrays
/// of scalars in the shader, a size that is a multiple of 16): the sun's uniform block and
/// a bundle's storage buffer hold the same bytes. The lookup branches on `projection`.
struct GpuGrid {
  /// The world-to-light mapping: origin and frame for both projections (a perspective
  /// grid's origin is its apex); offset and scale for an orthographic one only (0 else),
  /// as OrthoGrid::lookupMapping gives them, so the GPU evaluates the CPU's constants.
  LookupMapping mapping;
  double tanHalfFov, tanCone, near, far, logRatio;  // perspective only (0 else)
  uint32_t projection;      // Projection
  uint32_t log2Resolution;
  uint32_t headerWord;      // the DAG's header in the words it is read from (a bundle's pool: 48 k)
  uint32_t firstBoundary;   // perspective: where its R + 1 slice boundaries start in the bundle's table
  uint32_t light;           // a bundle's grid: its light
  uint32_t depthShift;      // orthographic: OrthoGrid::depthShift, what lookups offset by (0 else)
};
static_assert(sizeof(GpuGrid) == 208, "cpvs_shadow.glsl's CpvsGrid is 208 bytes");

/// The record of the grid `spec` describes (validated as orthoGridOf and perspectiveGridOf
/// do: InputError naming `what`).
GpuGrid gpuGridOf(const GridSpec& spec, const std::string& what, uint32_t headerWord = 0, uint32_t firstBoundary = 0,
                  uint32_t light = 0);

}  // namespace cpvs
