// The step policy (sim/step_policy.hpp): hand-worked choices for each mode and limit.
#include "sim/step_policy.hpp"

#include "mesh/mesh.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace cutsim {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
const StepLimits kLimits{1.0e-3, 0.8e-3, 1.1e-3};  // exact, certified, estimate [s]

StepPolicy fraction(double f, LimitOf of, OnLimit on = OnLimit::Refuse) {
    StepPolicy p;
    p.fraction = f;
    p.of = of;
    p.onLimit = on;
    return p;
}

StepPolicy fixedStep(double value, OnLimit on) {
    StepPolicy p;
    p.fixed = true;
    p.value = value;
    p.onLimit = on;
    return p;
}

TEST(StepPolicy, FractionOfEachLimit) {
    EXPECT_DOUBLE_EQ(chooseStep(fraction(0.9, LimitOf::Exact), kLimits, true).dt, 0.9e-3);
    EXPECT_DOUBLE_EQ(chooseStep(fraction(0.9, LimitOf::Certified), kLimits, true).dt, 0.72e-3);
    EXPECT_DOUBLE_EQ(chooseStep(fraction(0.5, LimitOf::Estimate), kLimits, true).dt, 0.55e-3);
    EXPECT_EQ(chooseStep(fraction(0.9, LimitOf::Exact), kLimits, true).action, LimitAction::None);
    EXPECT_DOUBLE_EQ(chooseStep(fraction(0.9, LimitOf::Exact), kLimits, true).limit, 1.0e-3);
}

// 0.95 of the estimate is 1.045e-3 s, above the exact 1e-3 s: the on_limit rule decides.
TEST(StepPolicy, AboveTheExactLimit) {
    const StepChoice refused = chooseStep(fraction(0.95, LimitOf::Estimate), kLimits, true);
    EXPECT_EQ(refused.action, LimitAction::Refused);
    EXPECT_DOUBLE_EQ(refused.dt, 1.045e-3);  // the step that was asked, for the message
    const StepChoice clamped = chooseStep(fraction(0.95, LimitOf::Estimate, OnLimit::Clamp), kLimits, true);
    EXPECT_EQ(clamped.action, LimitAction::Clamped);
    EXPECT_DOUBLE_EQ(clamped.dt, 0.98e-3);  // kClampFraction of the exact limit
    const StepChoice damped = chooseStep(fraction(0.95, LimitOf::Estimate, OnLimit::Damp), kLimits, true);
    EXPECT_EQ(damped.action, LimitAction::Damped);
    EXPECT_DOUBLE_EQ(damped.dt, 1.045e-3);  // kept; the elements below it are damped
}

TEST(StepPolicy, FixedStep) {
    EXPECT_DOUBLE_EQ(chooseStep(fixedStep(0.5e-3, OnLimit::Refuse), kLimits, true).dt, 0.5e-3);
    EXPECT_EQ(chooseStep(fixedStep(1.0e-3, OnLimit::Refuse), kLimits, true).action, LimitAction::None);  // at the limit
    EXPECT_EQ(chooseStep(fixedStep(1.5e-3, OnLimit::Refuse), kLimits, true).action, LimitAction::Refused);
    EXPECT_DOUBLE_EQ(chooseStep(fixedStep(1.5e-3, OnLimit::Clamp), kLimits, true).dt, 0.98e-3);
}

// Backward Euler is unconditionally stable: any step is taken as asked.
TEST(StepPolicy, ImplicitSchemeTakesAnyStep) {
    const StepChoice c = chooseStep(fixedStep(1.0, OnLimit::Refuse), kLimits, false);
    EXPECT_DOUBLE_EQ(c.dt, 1.0);
    EXPECT_EQ(c.action, LimitAction::None);
}

// After a cut with cutting.exact_after_cut false the exact limit is unknown: the certified bound
// stands in for it, both as "exact" and as the limit checked against.
TEST(StepPolicy, UnknownExactLimitUsesTheCertifiedBound) {
    const StepLimits lim{kNaN, 0.8e-3, 1.1e-3};
    const StepChoice c = chooseStep(fraction(0.9, LimitOf::Exact), lim, true);
    EXPECT_DOUBLE_EQ(c.dt, 0.72e-3);
    EXPECT_DOUBLE_EQ(c.limit, 0.8e-3);
    EXPECT_EQ(chooseStep(fixedStep(0.9e-3, OnLimit::Clamp), lim, true).dt, 0.98 * 0.8e-3);
}

// The same rule after a cut: a fraction follows the new limit, down and up.
TEST(StepPolicy, FractionFollowsTheLimitThroughCuts) {
    const StepPolicy p = fraction(0.9, LimitOf::Exact);
    EXPECT_DOUBLE_EQ(chooseStep(p, {0.8e-3, 0.6e-3, 0.9e-3}, true).dt, 0.72e-3);
    EXPECT_DOUBLE_EQ(chooseStep(p, {1.2e-3, 0.9e-3, 1.3e-3}, true).dt, 1.08e-3);
}

TEST(StepPolicy, NamesRoundTrip) {
    for (LimitOf l : {LimitOf::Exact, LimitOf::Certified, LimitOf::Estimate})
        EXPECT_EQ(parseLimitOf(limitOfName(l)), l);
    for (OnLimit o : {OnLimit::Refuse, OnLimit::Clamp, OnLimit::Damp}) EXPECT_EQ(parseOnLimit(onLimitName(o)), o);
    EXPECT_THROW(parseOnLimit("ignore"), InputError);
    EXPECT_STREQ(limitActionName(LimitAction::Clamped), "clamped");
}

}  // namespace
}  // namespace cutsim
