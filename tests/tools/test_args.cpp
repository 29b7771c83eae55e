// The command-line walker shared by `graphfrac run` and graphfrac-demo: both spellings of an
// option's value, missing and malformed values (integer lists too), and positionals that look
// like "a=b".
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cli/args.h"

namespace gf::cli {
namespace {

/// Walks `args` (args[0] = the program) and records "name" or "name=value" per option, where
/// every option but --flag takes a value.
std::vector<std::string> walk(std::vector<std::string> args) {
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  ArgParser p(int(argv.size()), argv.data());
  std::vector<std::string> out;
  while (p.next()) {
    if (!p.isOption() || p.name() == "--flag") {
      out.push_back(p.name());
      continue;
    }
    std::string v;
    out.push_back(p.value(v) ? p.name() + "=" + v : p.name() + " (missing)");
  }
  return out;
}

TEST(Args, ValuesFollowOrJoinTheirOption) {
  EXPECT_EQ(
      walk({"prog", "--out", "dir", "--frames=10", "--flag", "scene=1.json", "--out="}),
      (std::vector<std::string>{"--out=dir", "--frames=10", "--flag", "scene=1.json", "--out="}));
  EXPECT_EQ(walk({"prog", "--out"}), (std::vector<std::string>{"--out (missing)"}));
}

TEST(Args, NumbersAreCheckedWhole) {
  int n = -1;
  EXPECT_TRUE(parseInt("42", 0, 100, n));
  EXPECT_EQ(n, 42);
  EXPECT_FALSE(parseInt("42x", 0, 100, n));
  EXPECT_FALSE(parseInt("101", 0, 100, n));
  EXPECT_FALSE(parseInt("99999999999999999999", 0, 100, n));  // overflows long long
  EXPECT_FALSE(parseInt("", 0, 100, n));
  EXPECT_EQ(n, 42);  // untouched by the failures
  double x = 0;
  EXPECT_TRUE(parseDouble("0.05", x));
  EXPECT_EQ(x, 0.05);
  EXPECT_FALSE(parseDouble("inf", x));
  EXPECT_FALSE(parseDouble("1e", x));

  std::vector<std::string> args = {"prog", "--strain", "-0.5", "--frames", "7"};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  ArgParser p(int(argv.size()), argv.data());
  double strain = 1;
  ASSERT_TRUE(p.next());
  EXPECT_FALSE(p.positiveValue(strain));  // consumed, but not > 0
  EXPECT_EQ(strain, 1);
  ASSERT_TRUE(p.next());
  EXPECT_EQ(p.name(), "--frames");
  int frames = 0;
  EXPECT_TRUE(p.intValue(1, 100, frames));
  EXPECT_EQ(frames, 7);
  EXPECT_FALSE(p.next());
}

TEST(Args, IntListsAreCheckedItemByItem) {
  std::vector<int> v = {9};
  EXPECT_TRUE(parseIntList("1,2,16", 0, 64, v));
  EXPECT_EQ(v, (std::vector<int>{1, 2, 16}));
  EXPECT_TRUE(parseIntList("3", 0, 64, v));
  EXPECT_EQ(v, (std::vector<int>{3}));
  for (const char* bad : {"", "1,x", "1,,2", "1,", ",1", "1,65", "-1", "1;2", "1.5"})
    EXPECT_FALSE(parseIntList(bad, 0, 64, v)) << bad;
  EXPECT_EQ(v, (std::vector<int>{3}));  // untouched by the failures
}

}  // namespace
}  // namespace gf::cli
