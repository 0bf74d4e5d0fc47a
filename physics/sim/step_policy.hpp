// The time-step policy of a scene: which step to take from the current stable limits, and what
// to do when it is above them. One pure function (chooseStep) decides it, before the first step
// and after every cut, for every driver (docs/method.md sec. 3).
#pragma once

#include <cstdint>
#include <string>

namespace cutsim {

// What the step is a fraction of.
enum class LimitOf : std::uint8_t {
    Exact,      // the exact critical step 2 / sqrt(lambda_max(M^-1 K)) (Lanczos)
    Certified,  // the Gershgorin bound, never above the exact value
    Estimate,   // the smallest per-element estimate (R1R); not a bound
};
// What a step above the exact limit of an explicit scheme does.
enum class OnLimit : std::uint8_t {
    Refuse,  // the run stops (exit 4); before the first step the scene is refused
    Clamp,   // the step becomes kClampFraction of the limit
    Damp,    // the step is kept; elements below it are damped (thesis eq. 3.16)
};
// What the choice did.
enum class LimitAction : std::uint8_t { None, Clamped, Damped, Refused };

LimitOf parseLimitOf(const std::string& name);  // exact | certified | estimate; throws InputError
OnLimit parseOnLimit(const std::string& name);  // refuse | clamp | damp; throws InputError
const char* limitOfName(LimitOf l);
const char* onLimitName(OnLimit o);
const char* limitActionName(LimitAction a);  // none | clamped | damped | refused

struct StepPolicy {
    bool fixed = false;  // true: `value`; false: `fraction` of the limit `of`
    double value = 0;    // fixed step [s]
    LimitOf of = LimitOf::Exact;
    double fraction = 0.9;  // of the limit [-]
    OnLimit onLimit = OnLimit::Refuse;
};

// The stable limits the policy reads [s]. exact is NaN when it is not known (a cut with
// cutting.exact_after_cut false): the certified bound stands in for it.
struct StepLimits {
    double exact = 0;
    double certified = 0;
    double estimate = 0;
};

// At exactly the limit the top mode is only marginally stable: a clamped step keeps 2% below it.
inline constexpr double kClampFraction = 0.98;

struct StepChoice {
    double dt = 0;     // step to take [s]; for Refused the step that was asked
    double limit = 0;  // limit the step was checked against [s] (exact, else certified)
    LimitAction action = LimitAction::None;
};

// The step of `policy` at `limits`. Explicit schemes check it against the exact limit (the
// certified one when the exact is unknown); backward Euler is unconditionally stable and takes it
// as asked. The same rule holds before the first step and after every cut: a fraction-of-limit
// policy follows the new limit, a fixed step stays fixed.
StepChoice chooseStep(const StepPolicy& policy, const StepLimits& limits, bool explicitScheme);

}  // namespace cutsim
