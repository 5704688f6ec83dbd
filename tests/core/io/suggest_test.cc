// The closest names offered in "unknown name" errors.
#include "core/io/suggest.h"

#include <gtest/gtest.h>

namespace invr {
namespace {

TEST(Suggest, TyposAndSwapsFindTheName) {
  const std::vector<std::string> fields = {"spp", "max_depth", "estimator", "ris_candidates", "seed"};
  EXPECT_EQ(closestNames("spq", fields), std::vector<std::string>{"spp"});
  EXPECT_EQ(closestNames("max_dpeth", fields), std::vector<std::string>{"max_depth"});  // two letters swapped
  EXPECT_EQ(closestNames("Estimator", fields), std::vector<std::string>{"estimator"});  // case
  EXPECT_EQ(closestNames("candidates", fields), std::vector<std::string>{"ris_candidates"});  // a part of it
  EXPECT_TRUE(closestNames("frobnicate", fields).empty());
  EXPECT_EQ(didYouMean("rnu", {"run", "render", "zoo"}), "; did you mean 'run'?");
  EXPECT_EQ(didYouMean("zzz", {"run"}), "");
  EXPECT_EQ(didYouMean("rde", {"red", "green", "reed"}), "; did you mean 'red'?");
  EXPECT_EQ(didYouMean("learning_rat", {"learning_rate", "learning_rate_half_life", "lower"}),
            "; did you mean 'learning_rate' or 'learning_rate_half_life'?");
}

}  // namespace
}  // namespace invr
