// SPDX-License-Identifier: Apache-2.0
#include "algo/neighbour_orders.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "algo/phase_engine.hpp"

namespace cylscan::algo {
namespace {

// A 6×5 image of Φ = 1000·x + 10·y (a plane: the mean of a pixel's 8
// neighbours is its own value), all valid but what each test marks.
struct Grid {
  static constexpr int kWidth = 6, kHeight = 5;
  std::vector<std::uint8_t> invalid = std::vector<std::uint8_t>(kWidth * kHeight, 0);
  std::vector<std::int64_t> absolute = std::vector<std::int64_t>(kWidth * kHeight, 0);
  Grid() {
    for (int y = 0; y < kHeight; ++y)
      for (int x = 0; x < kWidth; ++x)
        absolute[at(x, y)] = 1000 * x + 10 * y;
  }
  static std::size_t at(int x, int y) { return static_cast<std::size_t>(y * kWidth + x); }

  // Runs the rule with a quarter turn of 4000 units; returns the calls to decide.
  std::vector<std::pair<std::size_t, std::int64_t>> run(bool accept = true) {
    std::vector<std::pair<std::size_t, std::int64_t>> calls;
    decided = decideOrdersFromNeighbours(
        cv::Size(kWidth, kHeight), invalid.data(), kOrderInconsistent, std::int64_t{4000},
        [&](std::size_t j) { return absolute[j]; },
        [&](std::size_t i, std::int64_t mean) {
          calls.emplace_back(i, mean);
          return accept;
        });
    return calls;
  }
  std::size_t decided = 0;
};

TEST(NeighbourOrders, AnAmbiguousPixelOnASmoothSurfaceGetsItsNeighboursMean) {
  Grid g;
  g.invalid[Grid::at(2, 2)] = kOrderInconsistent;
  const auto calls = g.run();
  ASSERT_EQ(calls.size(), 1u);
  EXPECT_EQ(calls[0].first, Grid::at(2, 2));
  EXPECT_EQ(calls[0].second, 2020);  // the plane's own value there
  EXPECT_EQ(g.invalid[Grid::at(2, 2)], 0);
  EXPECT_EQ(g.decided, 1u);
}

TEST(NeighbourOrders, NeighboursThatDisagreeDecideNothing) {
  // A depth edge between columns 2 and 3: Φ jumps by more than a quarter turn.
  Grid g;
  for (int y = 0; y < Grid::kHeight; ++y)
    for (int x = 3; x < Grid::kWidth; ++x)
      g.absolute[Grid::at(x, y)] += 5000;
  g.invalid[Grid::at(2, 2)] = kOrderInconsistent;
  EXPECT_TRUE(g.run().empty());
  EXPECT_EQ(g.invalid[Grid::at(2, 2)], kOrderInconsistent);
  EXPECT_EQ(g.decided, 0u);
}

TEST(NeighbourOrders, FiveTrustedNeighboursAreNeededAndFourAreNot) {
  Grid g;
  g.invalid[Grid::at(2, 2)] = kOrderInconsistent;
  // Three of its neighbours dark: five trusted remain.
  g.invalid[Grid::at(1, 1)] = kLowModulation;
  g.invalid[Grid::at(2, 1)] = kLowModulation;
  g.invalid[Grid::at(3, 1)] = kLowModulation;
  EXPECT_EQ(g.run(false).size(), 1u);
  // A fourth: too few.
  g.invalid[Grid::at(1, 2)] = kSaturated;
  EXPECT_TRUE(g.run().empty());
  EXPECT_EQ(g.invalid[Grid::at(2, 2)], kOrderInconsistent);
}

TEST(NeighbourOrders, AnImageCornerHasTooFewNeighbours) {
  Grid g;
  g.invalid[Grid::at(0, 0)] = kOrderInconsistent;  // 3 neighbours
  g.invalid[Grid::at(0, 2)] = kOrderInconsistent;  // 5 neighbours, on the border
  const auto calls = g.run();
  ASSERT_EQ(calls.size(), 1u);
  EXPECT_EQ(calls[0].first, Grid::at(0, 2));
  // The mean of its 5 neighbours, which on the border lean to one side:
  // (10 + 30 + 1010 + 1020 + 1030) / 5.
  EXPECT_EQ(calls[0].second, 620);
}

TEST(NeighbourOrders, OnlyPixelsWhoseSoleReasonIsTheOrderAreDecided) {
  Grid g;
  g.invalid[Grid::at(2, 2)] = kOrderInconsistent | kLowModulation;
  g.invalid[Grid::at(4, 2)] = kOrderInconsistent | kSaturated;
  EXPECT_TRUE(g.run().empty());
}

TEST(NeighbourOrders, ARefusedDecisionLeavesThePixelInvalid) {
  Grid g;
  g.invalid[Grid::at(2, 2)] = kOrderInconsistent;
  EXPECT_EQ(g.run(false).size(), 1u);
  EXPECT_EQ(g.invalid[Grid::at(2, 2)], kOrderInconsistent);
  EXPECT_EQ(g.decided, 0u);
}

TEST(NeighbourOrders, ADecidedPixelNeverCountsAsAnotherOnesTrustedNeighbour) {
  // (2,2) has 7 trusted neighbours and is decided. (3,2) has 4 trusted ones
  // besides (2,2) (column 4 is dark where it touches it): if (2,2) counted
  // once decided, (3,2) would have 5.
  Grid g;
  g.invalid[Grid::at(2, 2)] = kOrderInconsistent;
  g.invalid[Grid::at(3, 2)] = kOrderInconsistent;
  g.invalid[Grid::at(4, 1)] = kLowModulation;
  g.invalid[Grid::at(4, 2)] = kLowModulation;
  g.invalid[Grid::at(4, 3)] = kLowModulation;
  const auto calls = g.run();
  ASSERT_EQ(calls.size(), 1u);
  EXPECT_EQ(calls[0].first, Grid::at(2, 2));
  EXPECT_EQ(g.invalid[Grid::at(3, 2)], kOrderInconsistent);
}

TEST(NeighbourOrders, TheReferenceFormTakesRadians) {
  // The same rule over doubles, as the reference path uses it.
  std::vector<std::uint8_t> invalid(9, 0);
  std::vector<double> absolute = {1.0, 1.1, 1.2, 1.0, 0.0, 1.2, 1.0, 1.1, 1.2};
  invalid[4] = kOrderInconsistent;
  double seen = 0;
  const std::size_t decided = decideOrdersFromNeighbours(
      cv::Size(3, 3), invalid.data(), kOrderInconsistent, 1.5707963,
      [&](std::size_t j) { return absolute[j]; },
      [&](std::size_t, double mean) {
        seen = mean;
        return true;
      });
  EXPECT_EQ(decided, 1u);
  EXPECT_NEAR(seen, 1.1, 1e-12);
}

}  // namespace
}  // namespace cylscan::algo
