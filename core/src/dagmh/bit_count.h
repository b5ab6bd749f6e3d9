// Set bits of a word, inline: the baseline x86-64 target has no popcount instruction, and
// std::popcount becomes a call into libgcc that a lookup makes per level and per value.
// Private to dagmh.
#pragma once

#include <cstdint>

namespace cpvs {

inline uint32_t bitCount(uint32_t v) {
  v = v - ((v >> 1) & 0x55555555u);
  v = (v & 0x33333333u) + ((v >> 2) & 0x33333333u);
  return (((v + (v >> 4)) & 0x0F0F0F0Fu) * 0x01010101u) >> 24;
}

}  // namespace cpvs
