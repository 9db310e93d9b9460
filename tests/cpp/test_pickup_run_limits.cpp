// The native pick-up budget (cpp/src/pickup/run_limits.hpp): when a call's runs may still start.
#include <gtest/gtest.h>

#include <chrono>

#include "../../cpp/src/pickup/run_limits.hpp"

using pickplan::pickup::detail::RunLimits;
using Clock = std::chrono::steady_clock;

TEST(PickupRunLimits, NoDeadlineNeverExpires) {
  RunLimits limits;
  limits.count(100.0, 1, false);
  EXPECT_FALSE(limits.limited());
  EXPECT_FALSE(limits.expired());
  EXPECT_EQ(limits.seconds_left(), 0.0);  // 0: no limit for Ipopt
}

TEST(PickupRunLimits, ALongRunAtItsIterationLimitDoesNotSpendWhatIsLeft) {
  // 1.2 s of 400 iterations (3 ms each) with 0.7 s left: a whole-run measure would stop the call
  // here; a run of 0.7 s still has time for 200 iterations.
  RunLimits limits;
  limits.deadline = Clock::now() + RunLimits::seconds(0.7);
  limits.count(1.2, 400, false);
  EXPECT_NEAR(limits.quickest_iteration, 0.003, 1e-12);
  EXPECT_FALSE(limits.expired());
  // Less left than one such iteration: spent.
  limits.deadline = Clock::now() + RunLimits::seconds(0.002);
  EXPECT_TRUE(limits.expired());
}

TEST(PickupRunLimits, ARunTheDeadlineCutIsNotAMeasure) {
  RunLimits limits;
  limits.deadline = Clock::now() + RunLimits::seconds(0.5);
  limits.count(0.1, 1000, true);  // cut short: its iterations say nothing of a whole run's pace
  EXPECT_EQ(limits.quickest_iteration, 0.0);
  limits.count(0.2, 0, false);  // no iteration: counted as one
  EXPECT_NEAR(limits.quickest_iteration, 0.2, 1e-12);
  limits.count(0.3, 10, false);
  EXPECT_NEAR(limits.quickest_iteration, 0.03, 1e-12);
}

TEST(PickupRunLimits, TheWorkBetweenRunsIsKeptBack) {
  RunLimits limits;
  limits.deadline = Clock::now() + RunLimits::seconds(10.0);
  limits.count(0.01, 1, false);
  limits.between = 4.0;  // the longest stretch between two runs so far
  EXPECT_LT(limits.seconds_left(), 6.0 + 1e-9);
  EXPECT_GT(limits.seconds_left(), 5.9);
  limits.between = 9.995;  // with one 10 ms iteration, less is left than a run needs
  EXPECT_TRUE(limits.expired());
}
