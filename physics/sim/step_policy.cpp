#include "sim/step_policy.hpp"

#include "mesh/mesh.hpp"
#include "sim/stages.hpp"

#include <cmath>

namespace cutsim {

LimitOf parseLimitOf(const std::string& name) {
    if (name == "exact") return LimitOf::Exact;
    if (name == "certified") return LimitOf::Certified;
    if (name == "estimate") return LimitOf::Estimate;
    throw InputError("unknown limit '" + name + "' (exact, certified, estimate)");
}

OnLimit parseOnLimit(const std::string& name) {
    if (name == "refuse") return OnLimit::Refuse;
    if (name == "clamp") return OnLimit::Clamp;
    if (name == "damp") return OnLimit::Damp;
    throw InputError("unknown on_limit '" + name + "' (refuse, clamp, damp)");
}

const char* limitOfName(LimitOf l) {
    switch (l) {
    case LimitOf::Exact: return "exact";
    case LimitOf::Certified: return "certified";
    case LimitOf::Estimate: return "estimate";
    }
    return "?";
}

const char* onLimitName(OnLimit o) {
    switch (o) {
    case OnLimit::Refuse: return "refuse";
    case OnLimit::Clamp: return "clamp";
    case OnLimit::Damp: return "damp";
    }
    return "?";
}

const char* limitActionName(LimitAction a) {
    switch (a) {
    case LimitAction::None: return "none";
    case LimitAction::Clamped: return "clamped";
    case LimitAction::Damped: return "damped";
    case LimitAction::Refused: return "refused";
    }
    return "?";
}

StepChoice chooseStep(const StepPolicy& p, const StepLimits& lim, bool explicitScheme) {
    StepChoice c;
    // The exact limit when known; the certified bound (<= exact) stands in for it.
    const double exact = std::isnan(lim.exact) ? lim.certified : lim.exact;
    c.limit = exact;
    const double of = p.of == LimitOf::Exact ? exact : p.of == LimitOf::Certified ? lim.certified : lim.estimate;
    c.dt = p.fixed ? p.value : p.fraction * of;
    if (!explicitScheme || !(c.dt > exact)) return c;
    switch (p.onLimit) {
    case OnLimit::Refuse: c.action = LimitAction::Refused; break;
    case OnLimit::Clamp:
        c.dt = kClampFraction * exact;
        c.action = LimitAction::Clamped;
        break;
    case OnLimit::Damp: c.action = LimitAction::Damped; break;
    }
    return c;
}

// ---- a run's step (sim/stages.hpp) ----

void applyStepPolicy(const SimSetup& s, SimData& d, bool initial) {
    const StepChoice c = chooseStep(d.policy, d.limits, d.integrator != Integrator::BackwardEuler);
    if (c.action == LimitAction::Refused) {
        if (initial)
            throw InputError(s.scene.file + ": integrator.dt: " +
                             fmt("step %.6g s is above the exact stable limit %.6g s of %s", c.dt, c.limit,
                                 integratorName(d.integrator)) +
                             "; set integrator.dt.on_limit to \"clamp\" or \"damp\" to allow it");
        failRun(d, RunStatus::Refused,
                fmt("stopped: step %.6g s is above the stable limit %.6g s after the cut at t = %.4g s"
                    " (integrator.dt.on_limit is \"refuse\")",
                    c.dt, c.limit, d.state.time));
        d.choice.action = LimitAction::Refused;
        return;
    }
    d.choice = c;
    // Per-element damping factor alpha_e = (dt_e / dt)^2 where dt_e < dt (thesis eq. 3.16).
    if (c.action == LimitAction::Damped)
        d.alphaElem = elementAlpha(d.analyzer.estimates().r1r, c.dt);
    else
        d.alphaElem.resize(0);
    d.critical = 0;
    const Eigen::VectorXd& r1r = d.analyzer.estimates().r1r;
    for (Eigen::Index e = 0; e < r1r.size(); ++e) d.critical += r1r(e) < s.scene.capture.criticalFactor * c.dt;
    d.stepOptions = s.scene.stepOptions(d.integrator, c.dt, d.alphaElem);
}

}  // namespace cutsim
