// The child-code arithmetic against loops over the codes one child at a time.
#include <gtest/gtest.h>

#include "cpvs/dag/child_codes.h"

namespace cpvs {
namespace {

TEST(ChildCodes, RanksCountsAndValidityOverEveryCodeWord) {
  for (uint32_t codes = 0; codes <= 0xFFFFu; ++codes) {
    int refs = 0;
    bool valid = true;
    for (int c = 0; c < kChildren; ++c) {
      const uint32_t code = (codes >> (2 * c)) & 3u;
      ASSERT_EQ(childCode(codes, c), code);
      if (code == kRef) {
        ASSERT_EQ(refRank(codes, c), refs) << std::hex << codes << " child " << c;
      }
      refs += code == kRef;
      valid = valid && code != 3;
    }
    ASSERT_EQ(refCount(codes), refs) << std::hex << codes;
    ASSERT_EQ(validCodes(codes), valid) << std::hex << codes;
  }
}

TEST(ChildCodes, ChildOfVoxelWalksTheOctreeDownToSlices) {
  // Level l's node covers 2^(l+3) voxels; its child of a voxel is the octant of the
  // voxel's position within it, halves of 2^(l+2); level 0's children are depth slices.
  for (int level = 0; level < 6; ++level)
    for (uint64_t x = 0; x < 64; x += 5)
      for (uint64_t y = 0; y < 64; y += 7)
        for (uint64_t z = 0; z < 64; z += 3) {
          const uint64_t half = uint64_t(1) << (level + 2);
          const int want = level == 0 ? int(z % 8)
                                      : int((z / half % 2) * 4 + (y / half % 2) * 2 + (x / half % 2));
          ASSERT_EQ(childOfVoxel(level, x, y, z), want) << level << " " << x << " " << y << " " << z;
        }
  EXPECT_EQ(leafBit(3, 5), 43);
  EXPECT_EQ(leafBit(8 + 3, 16 + 5), 43);
  EXPECT_EQ(octant(1, 0, 1), 5);
}

}  // namespace
}  // namespace cpvs
