#include "cpvs/bake/column_masks.h"

#include "cpvs/base/error.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <limits>
#include <stdexcept>

namespace cpvs {

void litColumnMasks(uint32_t width, uint32_t height, uint32_t R, ColumnMasks& out) {
  if (width % 8 || height % 8) throw std::invalid_argument("litColumnMasks: size not a multiple of 8");
  out.columnsX = width / 8;
  out.columnsY = height / 8;
  out.resolution = R;
  const size_t n = size_t(out.columnsX) * out.columnsY;
  out.begin.assign(n + 1, 0);
  out.slice.clear();
  out.mask.clear();
  out.firstShadow.assign(n, R);
  out.fullShadow.assign(n, R);
}

void buildColumnMasks(const TexelSlices& depths, uint32_t width, uint32_t height, uint32_t R,
                      UndefinedRule rule, ColumnMasks& out) {
  if (width % 8 || height % 8) throw std::invalid_argument("buildColumnMasks: size not a multiple of 8");
  out.columnsX = width / 8;
  out.columnsY = height / 8;
  out.resolution = R;
  size_t n = size_t(out.columnsX) * out.columnsY;
  out.firstShadow.assign(n, R);
  out.fullShadow.assign(n, R);
  // Columns of one row are resolved together, then rows are concatenated in order.
  std::vector<std::vector<uint32_t>> rowSlices(out.columnsY), rowCounts(out.columnsY);
  std::vector<std::vector<uint64_t>> rowMasks(out.columnsY);
  tbb::parallel_for(uint32_t(0), out.columnsY, [&](uint32_t cy) {
    auto& counts = rowCounts[cy];
    counts.resize(out.columnsX);
    for (uint32_t cx = 0; cx < out.columnsX; ++cx) {
      const size_t at = size_t(cy) * 8 * width + size_t(cx) * 8;
      size_t before = rowSlices[cy].size();
      size_t c = out.column(cx, cy);
      columnTransitionsOfRows(depths.firstUndefined.data() + at, depths.firstShadowed.data() + at, width, R, rule,
                              rowSlices[cy], rowMasks[cy], out.firstShadow[c], out.fullShadow[c]);
      counts[cx] = uint32_t(rowSlices[cy].size() - before);
    }
  });
  out.begin.assign(n + 1, 0);
  size_t total = 0;
  for (uint32_t cy = 0; cy < out.columnsY; ++cy)
    for (uint32_t cx = 0; cx < out.columnsX; ++cx) {
      out.begin[out.column(cx, cy)] = uint32_t(total);
      total += rowCounts[cy][cx];
    }
  out.begin[n] = uint32_t(total);
  out.slice.resize(total);
  out.mask.resize(total);
  for (uint32_t cy = 0; cy < out.columnsY; ++cy) {
    size_t at = out.begin[out.column(0, cy)];
    std::copy(rowSlices[cy].begin(), rowSlices[cy].end(), out.slice.begin() + at);
    std::copy(rowMasks[cy].begin(), rowMasks[cy].end(), out.mask.begin() + at);
  }
}

void appendColumnRows(ColumnMasks& to, const ColumnMasks& rows) {
  if (to.begin.empty()) {  // nothing yet: the rows are the block so far
    to = rows;
    return;
  }
  CPVS_CHECK(rows.columnsX == to.columnsX && rows.resolution == to.resolution);
  const uint64_t base = to.begin.back();
  if (base + rows.slice.size() > std::numeric_limits<uint32_t>::max())
    throw std::length_error("appendColumnRows: more than 2^32 transitions in one block");
  to.columnsY += rows.columnsY;
  for (size_t c = 1; c < rows.begin.size(); ++c) to.begin.push_back(uint32_t(base + rows.begin[c]));
  to.slice.insert(to.slice.end(), rows.slice.begin(), rows.slice.end());
  to.mask.insert(to.mask.end(), rows.mask.begin(), rows.mask.end());
  to.firstShadow.insert(to.firstShadow.end(), rows.firstShadow.begin(), rows.firstShadow.end());
  to.fullShadow.insert(to.fullShadow.end(), rows.fullShadow.begin(), rows.fullShadow.end());
}

}  // namespace cpvs
