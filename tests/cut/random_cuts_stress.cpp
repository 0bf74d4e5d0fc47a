// The stress test of cutting: 500 random cut sequences on the liver and on a bar, each run at
// 0.9 of the current exact dt; none may blow up (inverted elements are counted and printed).
#include "random_cuts.hpp"


namespace cutsim {
namespace {

TEST(RandomCutsStress, Liver250) {
    const auto st = test::runRandomCuts(true, 250, 300, 11);
    test::printRandomCuts("liver", st);
    EXPECT_EQ(st.failures, 0) << st.firstFailure;
}

TEST(RandomCutsStress, Bar250) {
    const auto st = test::runRandomCuts(false, 250, 300, 12);
    test::printRandomCuts("bar", st);
    EXPECT_EQ(st.failures, 0) << st.firstFailure;
}

} // namespace
} // namespace cutsim
