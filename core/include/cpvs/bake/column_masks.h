// Visibility masks of 8x8-texel columns (§3.4).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/bake/texel_slices.h"

namespace cpvs {

/// The resolved voxels of a block of 8x8-texel columns. Each column is a monotone
/// sequence of 64-bit masks along depth: all lit (mask 0) before its first transition,
/// then each transition (slice, mask) replaces the mask from that slice on; bits only ever
/// turn on (shadowed). Bit (ty * 8 + tx) is texel (8 cx + tx, 8 cy + ty).
/// firstShadow is the first transition's slice (R if none) and fullShadow the slice from
/// which the mask is all ones (R if never).
struct ColumnMasks {
  uint32_t columnsX = 0, columnsY = 0;
  uint32_t resolution = 0;                  // R
  std::vector<uint32_t> begin;              // columnsX * columnsY + 1, into slice/mask
  std::vector<uint32_t> slice;
  std::vector<uint64_t> mask;
  std::vector<uint32_t> firstShadow, fullShadow;

  size_t column(uint32_t cx, uint32_t cy) const { return size_t(cy) * columnsX + cx; }
};

/// Resolves the texel depths of a width x height block (multiples of 8) into column masks.
/// Every voxel's value satisfies its texel's classification: lit where it must be lit,
/// shadowed where it must be shadowed, and a choice by `rule` where it is undefined.
/// Depends only on each column's own texels, so the result is independent of tiling.
void buildColumnMasks(const TexelSlices& depths, uint32_t width, uint32_t height, uint32_t R,
                      UndefinedRule rule, ColumnMasks& out);

/// Appends the columns of `rows` (as wide as `to`) below those of `to` (a `to` with no
/// `begin` yet becomes `rows`): the masks of a block resolved strip by strip are the
/// block's. std::length_error past 2^32 transitions.
void appendColumnRows(ColumnMasks& to, const ColumnMasks& rows);

/// Appends the transitions of one 8x8 column, texel (tx, ty) at ty * 8 + tx: lo is the
/// first undefined slice, hi the first shadowed one (hi >= lo). Returns firstShadow and
/// fullShadow as ColumnMasks stores them. What buildColumnMasks runs per column.
void columnTransitions(const uint32_t lo[64], const uint32_t hi[64], uint32_t R, UndefinedRule rule,
                       std::vector<uint32_t>& slices, std::vector<uint64_t>& masks, uint32_t& firstShadow,
                       uint32_t& fullShadow);

/// columnTransitions of the column whose texel (tx, ty) is at lo[ty * stride + tx] and
/// hi[ty * stride + tx], hi read as at least lo: a column inside a block's rows.
void columnTransitionsOfRows(const uint32_t* lo, const uint32_t* hi, size_t stride, uint32_t R, UndefinedRule rule,
                             std::vector<uint32_t>& slices, std::vector<uint64_t>& masks, uint32_t& firstShadow,
                             uint32_t& fullShadow);

/// The aligned rule's ranges for one 8x8 column (texel t: lit before lo[t], shadowed from
/// hi[t]; hi < lo reads as hi = lo): narrowed so that the column is wholly lit below the
/// last multiple of 8 that every texel allows lit, and wholly shadowed from the first
/// multiple of 8 that every texel allows shadowed; where every texel allows one common
/// multiple of 8, lit up to the last such and shadowed from it. Every narrowed range lies
/// inside its texel's own. The aligned rule is the new rule on these.
void alignedRanges(const uint32_t lo[64], const uint32_t hi[64], uint32_t R, uint32_t outLo[64], uint32_t outHi[64]);

/// The masks of a width x height block that no surface touches: every column all lit.
void litColumnMasks(uint32_t width, uint32_t height, uint32_t R, ColumnMasks& out);

}  // namespace cpvs
