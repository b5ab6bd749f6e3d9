// The bake options' names, bounds and the tile plan.
#include <gtest/gtest.h>

#include <string>

#include "cpvs/bake/options.h"
#include "cpvs/bake/tile_plan.h"
#include "cpvs/base/error.h"

namespace cpvs {
namespace {

template <class Option>
void expectNamesRoundTrip() {
  const auto& names = OptionNames<Option>::kNames;
  for (size_t i = 0; i < names.size(); ++i) {
    EXPECT_EQ(parseOption<Option>(names[i], "--x"), Option(i));
    EXPECT_STREQ(optionName(Option(i)), names[i]);
    EXPECT_TRUE(isOptionValue<Option>(int64_t(i)));
  }
  EXPECT_FALSE(isOptionValue<Option>(int64_t(names.size())));
  EXPECT_FALSE(isOptionValue<Option>(-1));
}

TEST(BakeOptions, NamesRoundTripAndUnknownNamesAreRefused) {
  expectNamesRoundTrip<ClosedMode>();
  expectNamesRoundTrip<ExitMode>();
  expectNamesRoundTrip<UndefinedRule>();
  expectNamesRoundTrip<CompressMode>();
  expectNamesRoundTrip<HashKind>();
  expectNamesRoundTrip<Renderer>();
  try {
    parseOption<CompressMode>("zip", "--compress");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "--compress: 'zip' is not one of topdown, bottomup, none");
  }
  EXPECT_EQ(describe(BakeOptions{}),
            "closed auto, exit exact, cull on, compress topdown, undefined aligned, renderer raster, tile 4096");
}

TEST(BakeOptions, OneTileSizeRule) {
  EXPECT_EQ(log2TileSizeOf(8, "t"), 3);
  EXPECT_EQ(log2TileSizeOf(4096, "t"), 12);
  EXPECT_EQ(log2TileSizeOf(uint64_t(1) << 20, "t"), 20);
  for (uint64_t bad : {uint64_t(0), uint64_t(4), uint64_t(100), uint64_t(1) << 21, uint64_t(1) << 40})
    EXPECT_THROW(log2TileSizeOf(bad, "--tile-size"), InputError) << bad;
}

TEST(TilePlan, TilesRowByRowAndATileLargerThanTheGridIsTheGrid) {
  const TilePlan plan(12, 10);
  EXPECT_EQ(plan.perSide(), 4u);
  EXPECT_EQ(plan.count(), 16u);
  for (uint64_t i = 0; i < plan.count(); ++i) {
    const TileCoord t = plan.tile(i);
    EXPECT_EQ(t.x, i % 4);
    EXPECT_EQ(t.y, i / 4);
    EXPECT_EQ(plan.index(t), i);
  }
  const TilePlan whole(8, 12);
  EXPECT_EQ(whole.count(), 1u);
  EXPECT_EQ(whole.log2TileSize(), 8);
}

}  // namespace
}  // namespace cpvs
