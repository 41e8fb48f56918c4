// formatted(): printf into a std::string, of any length.
#include "deformable_flsm/runtime/format.h"

#include <gtest/gtest.h>

#include <string>

using namespace deformable_flsm;

TEST(Format, AsPrintfWouldPrint) {
  EXPECT_EQ(formatted("%s %d %.2f %zu", "a", 3, 0.5, static_cast<std::size_t>(7)), "a 3 0.50 7");
  EXPECT_EQ(formatted("no arguments"), "no arguments");
  EXPECT_EQ(formatted("%s", ""), "");
}

TEST(Format, LongerThanAnyFixedBuffer) {
  const std::string long_(5000, 'x');
  EXPECT_EQ(formatted("<%s>", long_.c_str()), "<" + long_ + ">");
}
