// Short version of the random-cut stress (the long one is tests/cut/random_cuts_stress.cpp).
#include "random_cuts.hpp"

namespace cutsim {
namespace {

TEST(RandomCuts, LiverShort) {
    const auto st = test::runRandomCuts(true, 6, 150, 1);
    test::printRandomCuts("liver", st);
    EXPECT_EQ(st.failures, 0) << st.firstFailure;
    EXPECT_GT(st.minDtRatio, 0.5);
}

TEST(RandomCuts, BarShort) {
    const auto st = test::runRandomCuts(false, 6, 150, 2);
    test::printRandomCuts("bar", st);
    EXPECT_EQ(st.failures, 0) << st.firstFailure;
    EXPECT_GT(st.minDtRatio, 0.5);
}

// The same sequences at 1.2 x the exact step of the cut mesh blow up: the detector works and the
// limit the analyser gives after each cut is the real one.
TEST(RandomCuts, AboveTheLimitBlowsUp) {
    const auto st = test::runRandomCuts(false, 3, 400, 2, MassLumping::Enrichment, 1.2);
    test::printRandomCuts("bar at 1.2 dt", st);
    EXPECT_EQ(st.failures, st.runs);
}

} // namespace
} // namespace cutsim
