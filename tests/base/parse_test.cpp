// Parsing of user text, and the checks of the error policy.
#include <gtest/gtest.h>

#include <string>

#include "cpvs/base/error.h"
#include "cpvs/base/parse.h"
#include "error_testing.h"

namespace cpvs {
namespace {

using testing::inputErrorOf;

TEST(Parse, ListsNumbersVectorsResolutions) {
  EXPECT_EQ(splitList(" a, b ,c"), (std::vector<std::string>{"a", "b", "c"}));
  EXPECT_EQ(splitList("a,,b"), (std::vector<std::string>{"a", "", "b"}));
  EXPECT_TRUE(splitList("").empty());
  EXPECT_EQ(parseNumbers("1, 2.5,-3e2", "--x"), (std::vector<double>{1, 2.5, -300}));
  EXPECT_NE(inputErrorOf([] { parseNumbers("1,x", "--x"); }).find("--x: 'x' is not a number"), std::string::npos);
  EXPECT_NE(inputErrorOf([] { parseNumbers("1,inf", "--x"); }).find("not finite"), std::string::npos);
  EXPECT_EQ(parseVec3("1,2,3", "--p"), (Vec3{1, 2, 3}));
  EXPECT_NE(inputErrorOf([] { parseVec3("1,2", "--p"); }).find("expected X,Y,Z"), std::string::npos);
  EXPECT_EQ(parseResolution("4K"), 12);
  EXPECT_EQ(parseResolution(" 16k "), 14);
  EXPECT_EQ(parseResolution("1024"), 10);
  EXPECT_NE(inputErrorOf([] { parseResolution("3000"); }).find("not a power of two"), std::string::npos);
  EXPECT_NE(inputErrorOf([] { parseResolution("4"); }).find("outside"), std::string::npos);
  EXPECT_NE(inputErrorOf([] { parseResolution("2048K"); }).find("outside"), std::string::npos);
  EXPECT_NE(inputErrorOf([] { parseResolution(""); }).find("empty"), std::string::npos);
}

TEST(Checks, AlwaysOnChecksAbortWithTheirPlace) {
  EXPECT_DEATH(CPVS_CHECK(1 + 1 == 3), "check failed: 1 \\+ 1 == 3");
  CPVS_CHECK(1 + 1 == 2);
  // FormatError is an InputError: callers that recover from bad input catch both.
  EXPECT_THROW(throw FormatError("bytes"), InputError);
}

}  // namespace
}  // namespace cpvs
