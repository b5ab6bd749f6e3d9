// A DAG-MH's depth values: one per full node, in preorder, each free within its node's
// interval, compressed in chunks of 32 (seed 001 §3.6, Alg. 2; the layout NOTES §2.2.5
// reconstructs). A chunk stores one representative that most of its intervals contain,
// and for the others a small integer i on the grid base + step * i that lands in each
// one's interval, bit-packed; where no grid of at most 24 bits fits, the raw float bits.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace cpvs {

/// Values per chunk: one bit each in a chunk's bitmap.
constexpr uint32_t kValuesPerChunk = 32;
/// The factor width of a chunk that stores raw float bits.
constexpr uint32_t kRawFactorBits = 32;
/// Zero bytes after the factor stream, so that a reader's 8-byte window stays in bounds.
constexpr size_t kFactorStreamPadding = 8;

/// One chunk's fixed part: 20 bytes, the same on disk, in memory and on the GPU.
struct ValueChunk {
  uint32_t bitmap = 0;        // bit k: value k is a factor (1) or the representative (0)
  float representative = 0;
  float base = 0, step = 0;   // a factor i decodes to base + step * float(i), never fused
  uint32_t meta = 0;          // bits 0..4: factor bits - 1; bits 5..31: byte offset of the factors

  uint32_t factorBits() const { return (meta & 31u) + 1; }
  uint32_t factorByte() const { return meta >> 5; }
};
static_assert(sizeof(ValueChunk) == 20);

/// The largest factor stream a chunk's 27-bit byte offset reaches.
constexpr uint64_t kMaxFactorStreamBytes = uint64_t(1) << 27;

/// Every value of a DAG-MH, chunked.
struct ValueChunks {
  uint64_t count = 0;               // values
  std::vector<ValueChunk> chunks;   // ceil(count / 32)
  std::vector<uint8_t> factors;     // little-endian bit stream, kFactorStreamPadding zero bytes at its end

  /// Value `index` (< count), as the GPU decodes it.
  float value(uint64_t index) const;
  /// Bytes stored: the chunks and the factor stream.
  uint64_t bytes() const { return chunks.size() * sizeof(ValueChunk) + factors.size(); }
};

/// Chunks the values whose allowed intervals are [lo[k], hi[k]] (lo <= hi, finite, in
/// preorder): every decoded value lies in its interval. The same bytes for the same
/// intervals on every machine.
ValueChunks encodeValueChunks(const float* lo, const float* hi, size_t count);

/// What encodeValueChunks chose, for `cpvs inspect` (seed 001's Table 4).
struct ValueChunkStats {
  uint64_t values = 0, factors = 0, rawFactors = 0;
  uint64_t factorBitsTotal = 0;  // summed over the factors
};
ValueChunkStats valueChunkStats(const ValueChunks& values);

}  // namespace cpvs
