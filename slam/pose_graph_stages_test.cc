#include "slam/pose_graph_stages.h"

#include <optional>
#include <vector>

#include <gtest/gtest.h>

#include "core/check.h"

namespace sightmap::slam::internal {
namespace {

TEST(PoseGraphStages, ComponentsJoinTransitively) {
  Components components(5);
  components.Join(0, 1);
  components.Join(3, 1);
  EXPECT_EQ(components.Find(0), components.Find(3));
  EXPECT_NE(components.Find(0), components.Find(2));
  EXPECT_NE(components.Find(2), components.Find(4));
}

TEST(PoseGraphStages, SelectEdgesTakesThePartAroundAPose) {
  // Two parts, {0, 1, 2} and {3, 4}; the edge 2-3 that would join them is switched off.
  const EdgeEnds ends = {{0, 1}, {1, 2}, {3, 4}, {2, 3}};
  const std::vector<bool> active = {true, true, true, false};
  const std::vector<bool> all_free(5, true);
  EXPECT_EQ(SelectEdges(ends, active, all_free, std::nullopt),
            (std::vector<bool>{true, true, true, false}));
  EXPECT_EQ(SelectEdges(ends, active, all_free, size_t{0}),
            (std::vector<bool>{true, true, false, false}));
  EXPECT_EQ(SelectEdges(ends, active, all_free, size_t{4}),
            (std::vector<bool>{false, false, true, false}));
}

TEST(PoseGraphStages, SelectEdgesDropsEdgesWithNoFreeEnd) {
  const EdgeEnds ends = {{0, 1}, {1, 2}, {2, 3}};
  const std::vector<bool> active(3, true);
  // A window of poses 2 and 3: the edge 0-1 lies outside it, 1-2 is its border.
  const std::vector<bool> free = {false, false, true, true};
  EXPECT_EQ(SelectEdges(ends, active, free, std::nullopt), (std::vector<bool>{false, true, true}));
  EXPECT_EQ(SelectEdges(ends, active, free, size_t{0}), (std::vector<bool>{false, true, true}));
  EXPECT_THROW(SelectEdges(ends, active, free, size_t{4}), Error);
  EXPECT_THROW(SelectEdges(ends, {true}, free, std::nullopt), Error);
}

TEST(PoseGraphStages, EachComponentHoldsItsPinnedPosesOrElseItsFirst) {
  const EdgeEnds ends = {{1, 2}, {0, 1}, {3, 4}, {4, 5}, {2, 6}};
  // 4-5 carries no information (it ties nothing); 2-6 is not solved.
  const std::vector<bool> solved = {true, true, true, true, false};
  const std::vector<bool> ties = {true, true, true, false, true};
  std::vector<bool> pinned(7, false);
  pinned[4] = true;
  EXPECT_EQ(HeldPoses(ends, solved, ties, pinned),
            // {0, 1, 2} holds its first pose; {3, 4} its pinned 4 only; 5 is alone in its
            // component and holds itself; 6 is not in the problem.
            (std::vector<bool>{true, false, false, false, true, true, false}));
  // Two pinned poses in one component are both held, and nothing else there.
  pinned[0] = pinned[2] = true;
  EXPECT_EQ(HeldPoses(ends, solved, ties, pinned),
            (std::vector<bool>{true, false, true, false, true, true, false}));
  // A pinned pose that no solved edge touches is not in the problem, so not held.
  pinned[6] = true;
  EXPECT_FALSE(HeldPoses(ends, solved, ties, pinned)[6]);
  EXPECT_THROW(HeldPoses(ends, {true}, ties, pinned), Error);
}

TEST(PoseGraphStages, WorstLoopIsTheLargestChiSquareAboveTheLimit) {
  const std::vector<std::optional<double>> chi2 = {std::nullopt, 5.0, 12.0, 7.0, 12.5};
  EXPECT_EQ(WorstLoop(chi2, 10.0), std::optional<size_t>(4));
  EXPECT_EQ(WorstLoop(chi2, 12.5), std::nullopt);  // at the limit is consistent
  EXPECT_EQ(WorstLoop({12.0, std::nullopt, 12.0}, 10.0), std::optional<size_t>(0));
  EXPECT_EQ(WorstLoop({std::nullopt, std::nullopt}, 0.0), std::nullopt);
  EXPECT_EQ(WorstLoop({}, 0.0), std::nullopt);
}

}  // namespace
}  // namespace sightmap::slam::internal
