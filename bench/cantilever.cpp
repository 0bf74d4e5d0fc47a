// The reference problems of `cutsim bench accuracy`: the cantilever (meshes, static and frequency
// runs, runs that take turns) and its converged references by Richardson extrapolation.
#include "bench/bench.hpp"

#include "bench/oscillation.hpp"
#include "timestep/modes.hpp"
#include "util/stopwatch.hpp"

#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <vector>

namespace cutsim::bench {
namespace {

// A run has diverged once a node moves faster than anything a bending bar or a sagging organ
// reaches (tip speeds here are below 1 m/s): stop it instead of stepping overflowing values.
bool runaway(const State& s) { return !(s.v.cwiseAbs().maxCoeff() < 1e3); }

}  // namespace

// ---- the cantilever ----

Model cantileverModel(const Cantilever& c, int nyz, ElementModel em, BoxSplit split) {
    Model m = buildModel(boxMesh(c.L, c.h, c.h, 10 * nyz, nyz, nyz, split), c.material, em);
    std::vector<int> clamp;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.X(0, i) < 1e-9 * c.L) clamp.push_back(i);
    fixNodes(m, clamp);
    m.gravity << 0, 0, -9.81;
    return m;
}

double tipDeflection(const Model& m, const Eigen::Matrix3Xd& x) {
    const double L = m.X.row(0).maxCoeff();
    double sum = 0;
    int n = 0;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.X(0, i) > L * (1 - 1e-9)) {
            sum += x(2, i) - m.X(2, i);
            ++n;
        }
    return n ? sum / n : 0.0;
}

BenchPoint runStaticPoint(const AccuracyContext& ctx, const Model& m0, const StepOptions& opt,
                          const std::string& config, const TipProbe& probe) {
    Model m = m0;
    m.massDamping = ctx.bar.damping;
    State s = makeState(m);
    Stepper st;
    const long n = static_cast<long>(std::ceil(ctx.bar.staticTime / opt.dt - 1e-9));
    const auto t0 = WallClock::now();
    bool diverged = false;
    for (long k = 0; k < n && !diverged; ++k) {
        st.step(m, s, opt);
        diverged = s.flags.nonFinite != 0 || ((k & 63) == 63 && runaway(s));
    }
    const double wall = secondsSince(t0);
    BenchPoint p;
    p.problem = probe.problem.empty() ? "cantilever_static" : probe.problem + "_static";
    p.config = config;
    p.dt = opt.dt;
    p.explicitScheme = opt.integrator != Integrator::BackwardEuler;
    p.wallPerSimSecond = wall / s.time;
    const double ref = probe.problem.empty() ? ctx.tipReference : probe.reference;
    const double tip = probe.tip ? probe.tip(m, s.x) : tipDeflection(m, s.x);
    p.error = diverged ? INFINITY : std::abs(tip - ref) / std::abs(ref);
    return p;
}

FrequencyRun::FrequencyRun(const AccuracyContext& ctx, const Model& m0, const StepOptions& opt, std::string config,
                           TipProbe probe)
    : ctx_(&ctx), m_(m0), opt_(opt), config_(std::move(config)), probe_(std::move(probe)) {
    m_.massDamping = 0;
    s_ = makeState(m_);
    n_ = static_cast<long>(std::ceil(ctx.bar.frequencyTime / opt.dt - 1e-9));
    t_.reserve(n_ + 1);
    y_.reserve(n_ + 1);
}

FrequencyRun::~FrequencyRun() = default;
FrequencyRun::FrequencyRun(FrequencyRun&&) noexcept = default;

double FrequencyRun::advance(double until) {
    double wall = 0;
    // the same steps in any slicing: the run's end is its step count, not a time
    while (k_ < n_ && !diverged_ && s_.time < until) {
        const auto t0 = WallClock::now();
        st_.step(m_, s_, opt_);
        wall += secondsSince(t0);
        diverged_ = s_.flags.nonFinite != 0 || ((k_ & 63) == 63 && runaway(s_));
        ++k_;
        t_.push_back(s_.time);
        // outside the timed part: a measurement, not the method
        y_.push_back(probe_.tip ? probe_.tip(m_, s_.x) : tipDeflection(m_, s_.x));
    }
    wall_ += wall;
    return wall;
}

BenchPoint FrequencyRun::point() const {
    BenchPoint p;
    p.problem = probe_.problem.empty() ? "cantilever_frequency" : probe_.problem + "_frequency";
    p.config = config_;
    p.dt = opt_.dt;
    p.explicitScheme = opt_.integrator != Integrator::BackwardEuler;
    p.wallPerSimSecond = s_.time > 0 ? wall_ / s_.time : INFINITY;
    const double ref = probe_.problem.empty() ? ctx_->frequencyReference : probe_.reference;
    const Oscillation mode = fitOscillation(t_, y_);
    if (diverged_ || mode.frequency <= 0 || mode.halfCycles < 2) {
        p.error = INFINITY;
        return p;
    }
    const double wRef = 2 * M_PI * ref;
    p.frequencyError = (mode.frequency - ref) / ref;
    p.dampingRatio = mode.decay / wRef;
    p.error = modeError({-mode.decay, 2 * M_PI * mode.frequency}, wRef);
    return p;
}

BenchPoint runFrequencyPoint(const AccuracyContext& ctx, const Model& m0, const StepOptions& opt,
                             const std::string& config, const TipProbe& probe) {
    FrequencyRun run(ctx, m0, opt, config, probe);
    run.advance(INFINITY);
    return run.point();
}

PairedRuns runPaired(std::vector<FrequencyRun>& runs, int slices) {
    PairedRuns out;
    out.sliceWall.assign(runs.size(), std::vector<double>(static_cast<size_t>(slices), 0.0));
    const double T = runs.empty() ? 0 : runs.front().context().bar.frequencyTime;
    for (int i = 0; i < slices; ++i) {
        const double until = i + 1 == slices ? INFINITY : T * (i + 1) / slices;
        // alternate the order, so that no run always follows the same one
        for (size_t j = 0; j < runs.size(); ++j) {
            const size_t r = i % 2 ? runs.size() - 1 - j : j;
            out.sliceWall[r][static_cast<size_t>(i)] = runs[r].advance(until);
        }
    }
    for (const auto& r : runs) {
        out.points.push_back(r.point());
        out.simTime.push_back(r.time());
    }
    return out;
}

double PairedRuns::costRatio(size_t a, size_t b, int from, int to) const {
    double wa = 0, wb = 0;
    for (int i = from; i < to; ++i) {
        wa += sliceWall[a][static_cast<size_t>(i)];
        wb += sliceWall[b][static_cast<size_t>(i)];
    }
    return wb > 0 && simTime[a] > 0 ? (wa / simTime[a]) / (wb / simTime[b]) : INFINITY;
}

// Linear static tip deflection K u = M g (small-displacement limit of the corotational model).
double linearStaticTip(const Model& m, const TipFn& tip) {
    int nf = 0;
    const auto map = freeDofMap(m, &nf);
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(freeStiffness(m, map, nf, nullptr));
    Eigen::VectorXd f(nf);
    for (int i = 0; i < m.nodes(); ++i)
        for (int k = 0; k < 3; ++k)
            if (map[3 * i + k] >= 0) f(map[3 * i + k]) = m.mass(i) * m.gravity(k);
    const Eigen::VectorXd u = ldlt.solve(f);
    Eigen::Matrix3Xd x = m.X;
    for (int i = 0; i < m.nodes(); ++i)
        for (int k = 0; k < 3; ++k)
            if (map[3 * i + k] >= 0) x(k, i) += u(map[3 * i + k]);
    return tip ? tip(m, x) : tipDeflection(m, x);
}

// First bending frequency in z with the lumped mass: the lowest eigenpairs y_j, lambda_j of
// M^-1/2 K M^-1/2 (shift-invert Lanczos about 0); of those, the mode that moves the tip face's
// mean z most under a load along z: the static share of mode j in it is
// (y_j . M^1/2 e_z) (mean tip z of M^-1/2 y_j) / lambda_j. (On a mesh whose bending stiffness has
// skew principal axes, two modes share a z load; this picks the one that carries more of it.)
double firstBendingFrequency(const Model& m) {
    const Modes modes = lowestModes(m, 4);
    const Eigen::VectorXd& lam = modes.lambda;
    const Eigen::MatrixXd& vec = modes.vectors;
    const std::vector<int>& map = modes.dofMap;
    const double L = m.X.row(0).maxCoeff();
    double best = -1, lambda = 0;
    for (int j = 0; j < lam.size(); ++j) {
        double load = 0, tip = 0;
        int nTip = 0;
        for (int i = 0; i < m.nodes(); ++i) {
            const int d = map[3 * i + 2];
            if (d < 0) continue;
            const double sm = std::sqrt(m.mass(i));
            load += vec(d, j) * sm;
            if (m.X(0, i) > L * (1 - 1e-9)) {
                tip += vec(d, j) / sm;
                ++nTip;
            }
        }
        const double share = std::abs(load * tip) / (nTip ? nTip : 1) / lam(j);
        if (share > best) {
            best = share;
            lambda = lam(j);
        }
    }
    return std::sqrt(lambda) / (2 * M_PI);
}

// Richardson extrapolation of values on meshes h and h / ratio for an O(h^2) method.
double richardson(double coarse, double fine, double ratio) { return fine + (fine - coarse) / (ratio * ratio - 1); }

double observedOrder(const std::vector<int>& levels, const std::vector<double>& v) {
    const size_t k = levels.size();
    if (k < 3) return NAN;
    const double n1 = levels[k - 3], n2 = levels[k - 2], n3 = levels[k - 1];
    const double q = (v[k - 3] - v[k - 2]) / (v[k - 2] - v[k - 1]);
    // (n1^-p - n2^-p) / (n2^-p - n3^-p) rises with p; bisect for the p that gives q.
    auto g = [&](double p) { return (std::pow(n1, -p) - std::pow(n2, -p)) / (std::pow(n2, -p) - std::pow(n3, -p)); };
    double lo = 0.1, hi = 8;
    if (!(q > g(lo) && q < g(hi))) return NAN;
    for (int it = 0; it < 100; ++it) {
        const double mid = 0.5 * (lo + hi);
        (g(mid) < q ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
}

BarReferences barReferences(const std::vector<int>& levels, const std::function<Model(int)>& model) {
    BarReferences r;
    for (int n : levels) {
        const Model m = model(n);
        r.tips.push_back(linearStaticTip(m));
        r.freqs.push_back(firstBendingFrequency(m));
    }
    const size_t k = levels.size() - 1;
    const double ratio = static_cast<double>(levels[k]) / levels[k - 1];
    r.tip = richardson(r.tips[k - 1], r.tips[k], ratio);
    r.frequency = richardson(r.freqs[k - 1], r.freqs[k], ratio);
    r.tipOrder = observedOrder(levels, r.tips);
    r.frequencyOrder = observedOrder(levels, r.freqs);
    return r;
}

}  // namespace cutsim::bench
