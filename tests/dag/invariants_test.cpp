// The DAG invariants: what every build, compression and merge produces holds them, and
// each kind of damage is named.
#include <gtest/gtest.h>

#include "cpvs/dag/compress.h"
#include "cpvs/dag/invariants.h"
#include "dag_testing.h"

namespace cpvs {
namespace {

Dag sample() {
  TexelSlices d = testing::syntheticSlices(64, true, 4);
  return testing::buildTiled(d, 6, 4, UndefinedRule::New, true, CompressMode::TopDown, HashKind::Xxh3);
}

std::string damaged(void (*damage)(Dag&)) {
  Dag dag = sample();
  damage(dag);
  return dagInvariantViolation(dag, true);
}

TEST(DagInvariants, BuiltDagsHoldThemAndEachDamageIsNamed) {
  EXPECT_EQ(dagInvariantViolation(sample(), true), "");
  TexelSlices d = testing::syntheticSlices(64, false, 2);
  for (CompressMode mode : {CompressMode::TopDown, CompressMode::BottomUp})
    EXPECT_EQ(dagInvariantViolation(testing::buildTiled(d, 6, 5, UndefinedRule::Old, false, mode, HashKind::WeakForTests), true),
              "");
  EXPECT_NE(damaged([](Dag& g) { g.levels[0].children[0] = uint32_t(g.leaves.size()); }).find("outside the level below"),
            std::string::npos);
  EXPECT_NE(damaged([](Dag& g) { g.levels[0].codes[0] |= 3; }).find("invalid child code"), std::string::npos);
  EXPECT_NE(damaged([](Dag& g) { g.levels[0].childBegin.back() += 1; }).find("child ranges"), std::string::npos);
  EXPECT_NE(damaged([](Dag& g) {
              g.leaves.push_back(g.leaves.front());
              g.leafHashes.push_back(g.leafHashes.front());
            }).find("not in canonical order"),
            std::string::npos);
  EXPECT_NE(damaged([](Dag& g) { g.roots.front().ref = {kRef, 1u << 30}; }).find("root 0 is invalid"), std::string::npos);
  EXPECT_NE(damaged([](Dag& g) { g.levelHashes.back().pop_back(); }).find("hashes do not match"), std::string::npos);
}

}  // namespace
}  // namespace cpvs
