// `cutsim bench accuracy`: error against cost on reference problems with known answers, the
// Pareto front of each, and the cost at 1% error explicit against implicit. Results are described
// in BENCHMARKS.md.
#include "bench/bench.hpp"
#include "bench/machine.hpp"
#include "bench/options.hpp"
#include "app/commands.hpp"
#include "sim/simulation.hpp"
#include "timestep/modes.hpp"
#include "util/atomic_file.hpp"
#include "util/stopwatch.hpp"
#include "sim/scene.hpp"

#include "bench/random_cuts.hpp"
#include "fem/forces.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "timestep/timestep.hpp"

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <nlohmann/json.hpp>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <random>
#include <sstream>
#include <stdexcept>
#include <tuple>

namespace cutsim::bench {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

double secondsSince(WallClock::time_point t) { return std::chrono::duration<double>(WallClock::now() - t).count(); }

// The configurations other files add (addAccuracyConfig), by group name.
std::vector<std::pair<std::string, AccuracyConfig>>& configs() {
    static std::vector<std::pair<std::string, AccuracyConfig>> c;
    return c;
}

}  // namespace

void addAccuracyConfig(const std::string& name, AccuracyConfig fn) { configs().emplace_back(name, std::move(fn)); }

void markPareto(std::vector<BenchPoint>& pts) {
    for (auto& p : pts) {
        p.pareto = std::isfinite(p.error) && std::isfinite(p.wallPerSimSecond);
        for (const auto& q : pts) {
            if (&q == &p || q.problem != p.problem || !std::isfinite(q.error) || !std::isfinite(q.wallPerSimSecond))
                continue;
            const bool noWorse = q.error <= p.error && q.wallPerSimSecond <= p.wallPerSimSecond;
            const bool better = q.error < p.error || q.wallPerSimSecond < p.wallPerSimSecond;
            if (noWorse && better) {
                p.pareto = false;
                break;
            }
        }
    }
}

double costAtError(const std::vector<BenchPoint>& pts, const std::string& problem, double maxError,
                   bool explicitScheme) {
    double best = -1;
    for (const auto& p : pts)
        // equal errors: within 1e-6 relative (backward Euler's two solvers agree to ~1e-12, so
        // at a common error a CG point must not hide the direct one). The Pareto marks stay strict.
        if (p.problem == problem && p.explicitScheme == explicitScheme && p.error <= maxError * (1 + 1e-6) &&
            (best < 0 || p.wallPerSimSecond < best))
            best = p.wallPerSimSecond;
    return best;
}

namespace {

// ---- bench accuracy ----

struct AccuracyArgs {
    bool json = false, tiny = false;
    std::string csv, plot, from;
    int maxRes = 4;
    std::vector<int> res;        // cantilever resolutions (empty: 1 .. maxRes)
    std::vector<int> refLevels;  // reference meshes (empty: 2, 4, 8)
    int implicitMaxRes = 4;
    int cgMaxRes = 0;
    int threads = 0;                // worker threads of the explicit runs (0: all cores)
    std::vector<std::string> only;  // configuration groups to run (empty: all)
};

bool selected(const AccuracyArgs& a, const std::string& group) {
    return a.only.empty() || std::find(a.only.begin(), a.only.end(), group) != a.only.end();
}

std::vector<BenchPoint> readPointsCsv(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw InputError(path, 0, "cannot read");
    std::vector<BenchPoint> pts;
    std::string line;
    int lineNo = 0;
    while (std::getline(in, line)) {
        ++lineNo;
        if (lineNo == 1 || line.empty()) continue;  // header problem,config,error,wall_per_sim_second,dt[,implicit]
        std::vector<std::string> f;
        std::stringstream ss(line);
        std::string cell;
        while (std::getline(ss, cell, ',')) f.push_back(cell);
        if (f.size() < 5) throw InputError(path, lineNo, "need problem,config,error,wall_per_sim_second,dt");
        BenchPoint p;
        p.problem = f[0];
        p.config = f[1];
        try {
            p.error = std::stod(f[2]);
            p.wallPerSimSecond = std::stod(f[3]);
            p.dt = std::stod(f[4]);
        } catch (const std::exception&) {
            throw InputError(path, lineNo, "error, wall_per_sim_second and dt must be numbers");
        }
        p.explicitScheme = !(f.size() > 5 && (f[5] == "1" || f[5] == "implicit"));
        // optional: pareto (recomputed), then frequency_error, damping_ratio, predicted_error
        double* extra[3] = {&p.frequencyError, &p.dampingRatio, &p.predictedError};
        for (size_t k = 7; k < f.size() && k < 10; ++k) {
            if (f[k].empty()) continue;
            try {
                *extra[k - 7] = std::stod(f[k]);
            } catch (const std::exception&) {
                throw InputError(path, lineNo,
                                 "frequency_error, damping_ratio and predicted_error must be numbers or empty");
            }
        }
        pts.push_back(p);
    }
    return pts;
}

std::string pointsCsv(const std::vector<BenchPoint>& pts) {
    std::ostringstream o;
    o << "problem,config,error,wall_per_sim_second,dt,scheme,pareto,frequency_error,damping_ratio,predicted_error\n";
    o.precision(8);
    auto opt = [&](double v) -> std::ostream& { return std::isfinite(v) ? o << "," << v : o << ","; };
    for (const auto& p : pts) {
        o << p.problem << "," << p.config << "," << p.error << "," << p.wallPerSimSecond << "," << p.dt << ","
          << (p.explicitScheme ? "explicit" : "implicit") << "," << (p.pareto ? 1 : 0);
        opt(p.frequencyError);
        opt(p.dampingRatio);
        opt(p.predictedError);
        o << "\n";
    }
    return o.str();
}

// Error against cost, log-log, one panel per problem; explicit, implicit and the Pareto front.
void plotPoints(const std::vector<BenchPoint>& pts, const std::string& out) {
    std::vector<std::string> problems;
    for (const auto& p : pts)
        if (std::find(problems.begin(), problems.end(), p.problem) == problems.end()) problems.push_back(p.problem);
    const fs::path dir = plotDataDir("plot");
    std::ostringstream g;
    // up to three panels a row
    const size_t cols = std::clamp<size_t>(problems.size(), 1, 3),
                 rows = std::max<size_t>(1, (problems.size() + 2) / 3);
    std::ostringstream terminal;
    terminal << "set terminal pngcairo size " << 700 * cols << "," << 560 * rows << " noenhanced";
    g << "set multiplot layout " << rows << "," << cols << "\n";
    g << "set logscale xy\nset grid\nset key bottom left\nset yrange [0.005:*]\n";
    g << "set xlabel 'wall time per simulated second [s/s]'\nset ylabel 'relative error'\n";
    for (size_t k = 0; k < problems.size(); ++k) {
        const std::string base = (dir / ("p" + std::to_string(k))).string();
        std::ofstream ex(base + "_explicit.dat"), im(base + "_implicit.dat"), pf(base + "_pareto.dat");
        std::vector<const BenchPoint*> front;
        for (const auto& p : pts) {
            if (p.problem != problems[k] || !std::isfinite(p.error) || p.error <= 0) continue;
            (p.explicitScheme ? ex : im) << p.wallPerSimSecond << " " << p.error << "\n";
            if (p.pareto) front.push_back(&p);
        }
        std::sort(front.begin(), front.end(),
                  [](auto* a, auto* b) { return a->wallPerSimSecond < b->wallPerSimSecond; });
        for (auto* p : front) pf << p->wallPerSimSecond << " " << p->error << "\n";
        const bool hasEx = ex.tellp() > 0, hasIm = im.tellp() > 0;
        ex.close();
        im.close();
        pf.close();
        g << "set title '" << problems[k] << "'\n";
        g << "plot 0.01 with lines dt 2 lc rgb 'gray' title '1%'";
        if (hasEx) g << ", '" << base << "_explicit.dat' with points pt 7 ps 1.2 lc rgb '#1f77b4' title 'explicit'";
        if (hasIm)
            g << ", '" << base << "_implicit.dat' with points pt 5 ps 1.2 lc rgb '#d62728' title 'backward Euler'";
        if (!front.empty())
            g << ", '" << base << "_pareto.dat' with linespoints pt 6 ps 2 lw 2 lc rgb 'black' title 'Pareto front'";
        g << "\n";
    }
    g << "unset multiplot\n";
    runGnuplot(dir.string(), terminal.str(), g.str(), out);
}

// Backward Euler's cost at 1% on a mesh too fine to run it for a simulated second: its wall time
// per step, measured, over the dt at which its first mode is 1% off (integratorMode, checked by
// predicted_error against the runs it makes in full on coarser meshes).
struct ImplicitProjection {
    int res = 0;
    long tets = 0;
    double meshFrequency = 0;  // first bending frequency of the mesh (Lanczos) [Hz]
    double meshError = 0;      // its error against the reference [-]
    double dt = 0;             // largest dt with error <= 1%; 0 when the mesh alone misses it [s]
    double directSeconds = 0;  // wall time of one step with the sparse LDL^T, median of the timed steps [s]
    double cgSeconds = 0;      // the same with CG at dt [s]
    int cgIterations = 0;      // CG iterations of the median step
    int steps = 0;             // steps timed per solver
    double stepSeconds() const { return std::min(directSeconds, cgSeconds); }
    const char* solver() const { return directSeconds <= cgSeconds ? "direct" : "cg"; }
    double cost = INFINITY;  // stepSeconds() / dt [s/s]
};

// An implicit point and the explicit runs that took turns with it (runPaired), on one mesh.
struct PairedComparison {
    BenchPoint implicitPoint;
    int slices = 0;
    struct Explicit {
        BenchPoint point;
        double ratio = 0;                      // implicit cost / explicit cost over the whole run
        double firstHalf = 0, secondHalf = 0;  // the same over the first and the last half of the slices
        double sliceMin = 0, sliceMax = 0;     // the smallest and largest ratio of one slice
    };
    std::vector<Explicit> runs;
};

// Turns of a paired comparison: 20 slices of 0.05 simulated s in the full run, each a few seconds
// of the machine's time on the finest bars.
constexpr int kPairedSlices = 20;

// Backward Euler at dt with the given linear solver.
StepOptions backwardEulerOptions(double dt, ImplicitSolver solver) {
    StepOptions opt{Integrator::BackwardEuler, dt};
    opt.solver = solver;
    return opt;
}

// Wall time of one backward-Euler step of m (the median of `steps`, after a first step that
// builds the pattern and its ordering), and the CG iterations of that step. The cantilever starts
// from rest under gravity, so the timed steps are those of the run's start.
std::pair<double, int> backwardEulerStepSeconds(const Model& m0, double dt, int steps, ImplicitSolver solver) {
    Model m = m0;
    m.massDamping = 0;
    State s = makeState(m);
    Stepper st;
    const StepOptions opt = backwardEulerOptions(dt, solver);
    st.step(m, s, opt);
    std::vector<std::pair<double, int>> w;
    for (int k = 0; k < steps; ++k) {
        const auto t0 = WallClock::now();
        st.step(m, s, opt);
        w.emplace_back(secondsSince(t0), st.lastSolverIterations());
    }
    std::sort(w.begin(), w.end());
    return w[w.size() / 2];
}

// The built-in cantilever configurations of `bench accuracy`, in the order they run: explicit runs on
// conforming meshes, per-element damping beyond the limit, the implicit reference (backward Euler
// run in full, or its step timed and its cost at 1% projected). Each point is logged on stderr as it
// comes (unless quiet).
class CantileverRuns {
public:
    CantileverRuns(const AccuracyContext& ctx, bool quiet, std::vector<ImplicitProjection>& proj,
                   std::vector<PairedComparison>& paired)
        : ctx_(ctx), quiet_(quiet), proj_(proj), paired_(paired), wRef_(2 * M_PI * ctx.frequencyReference),
          finest_(ctx.res.back()) {
        for (int r : ctx_.res) fMesh_.push_back(firstBendingFrequency(bar(r)));
    }

    std::vector<BenchPoint> run() {
        explicitRuns();
        dampedRuns();
        implicitRuns();
        return pts_;
    }

private:
    void log(const BenchPoint& p) {
        pts_.push_back(p);
        if (!quiet_)
            std::fprintf(stderr, "  %-22s %-40s error %.3e  cost %.4g s/s\n", p.problem.c_str(), p.config.c_str(),
                         p.error, p.wallPerSimSecond);
    }

    // A frequency point's predicted error: the integrator's mode formula on the mesh's own mode.
    BenchPoint predicted(BenchPoint p, const StepOptions& opt, double fMesh) const {
        if (p.problem == "cantilever_frequency" && fMesh > 0)
            p.predictedError = modeError(integratorMode(opt.integrator, 2 * M_PI * fMesh, opt.dt), wRef_);
        return p;
    }

    // The bench's bar is the mirrored split: the Kuhn split's skew bending axes make a z load
    // excite two modes of different frequency, and the tip's motion beat.
    Model bar(int r, BoxSplit split = BoxSplit::Mirrored) const {
        return cantileverModel(ctx_.bar, r, ElementModel::Corotational, split);
    }

    // Config of an explicit run: variant "", "kuhn " or "single " (the turns below repeat these names).
    static std::string explicitName(const char* variant, int r, double f) {
        char name[160];
        std::snprintf(name, sizeof name, "explicit %s%dx%dx%d f=%g", variant, 10 * r, r, r, f);
        return name;
    }

    // Conforming meshes at 0.9 of their exact limit, plain symplectic Euler; the Kuhn split beside
    // the mirrored one on the coarse meshes.
    void explicitRuns() {
        for (size_t i = 0; i < ctx_.res.size(); ++i) {
            const int r = ctx_.res[i];
            for (BoxSplit split : {BoxSplit::Mirrored, BoxSplit::Kuhn}) {
                const bool kuhn = split == BoxSplit::Kuhn;
                if (kuhn && r > 4) continue;
                const Model m = bar(r, split);
                const double dtExact = exactCriticalDt(m).dt;
                if (!kuhn && r == finest_) dtFinest_ = dtExact;
                // The finest mesh also at 0.98 and 0.999 of its limit: the limit is exact (Lanczos),
                // and plain schemes are stable to 0.999 of it (bench stability). That sweep is unloaded;
                // here the bar hangs under gravity, whose stress could lift the top eigenvalue past the
                // unloaded limit (a run that diverges shows as such).
                std::vector<double> fractions = {0.9};
                if (!kuhn && r == finest_) fractions.insert(fractions.end(), {0.98, 0.999});
                for (double f : fractions) {
                    const StepOptions opt{Integrator::SymplecticEuler, f * dtExact};
                    const std::string cfg = explicitName(kuhn ? "kuhn " : "", r, f);
                    log(runStaticPoint(ctx_, m, opt, cfg));
                    log(kuhn ? runFrequencyPoint(ctx_, m, opt, cfg)
                             : predicted(runFrequencyPoint(ctx_, m, opt, cfg), opt, fMesh_[i]));
                }
                // and with the element forces in single precision (integrator.precision), at 0.999
                if (!kuhn && r == finest_) {
                    Model ms = m;
                    ms.precision = ForcePrecision::Single;
                    const StepOptions opt{Integrator::SymplecticEuler, 0.999 * dtExact};
                    const std::string cfg = explicitName("single ", r, 0.999);
                    log(runStaticPoint(ctx_, ms, opt, cfg));
                    log(predicted(runFrequencyPoint(ctx_, ms, opt, cfg), opt, fMesh_[i]));
                }
            }
        }
    }

    // Per-element damping beyond the limit (thesis eq. 3.16) on the finest mesh up to N = 8.
    void dampedRuns() {
        int r = ctx_.res.front();
        for (int q : ctx_.res)
            if (q <= 8) r = q;
        const Model m = bar(r);
        const double dtExact = exactCriticalDt(m).dt;
        const Eigen::VectorXd r1r = estimateElements(m).r1r;
        for (double f : {1.5, 2.0}) {
            const Eigen::VectorXd alpha = elementAlpha(0.95 * r1r, f * dtExact);  // margin: see bench stability
            StepOptions opt{Integrator::SymplecticEuler, f * dtExact};
            opt.alphaElem = &alpha;
            char name[160];
            std::snprintf(name, sizeof name, "explicit alpha_e_0.95 %dx%dx%d f=%.1f", 10 * r, r, r, f);
            log(runStaticPoint(ctx_, m, opt, name));
            log(runFrequencyPoint(ctx_, m, opt, name));
        }
    }

    // The implicit reference: backward Euler at several steps, run in full on the meshes where a
    // simulated second is affordable; on every mesh, its step timed and its cost at 1% projected.
    void implicitRuns() {
        const std::vector<double> dts =
            ctx_.tiny ? std::vector<double>{0.01, 0.003} : std::vector<double>{0.1, 0.03, 0.01, 0.003};
        for (size_t i = 0; i < ctx_.res.size(); ++i) {
            const int r = ctx_.res[i];
            const Model m = bar(r);
            const double meshError = std::abs(fMesh_[i] - ctx_.frequencyReference) / ctx_.frequencyReference;
            if ((r >= 2 || ctx_.tiny) && r <= ctx_.implicitMaxRes) fullImplicitRuns(m, r, dts, fMesh_[i], meshError);
            const ImplicitProjection pr = projection(m, r, fMesh_[i], meshError);
            proj_.push_back(pr);
            if (r > ctx_.implicitMaxRes && r <= ctx_.cgMaxRes && pr.dt > 0) checkProjection(m, r, pr.dt, fMesh_[i]);
        }
    }

    // Backward Euler run in full at each of dts, and near the mesh's floor: the dt whose predicted
    // error is 1.2 x the mesh's own (at least 1%), so the front has a measured point where the time
    // error is small. Then CG where it can pay: the smallest step, where dt^2 K is smallest against M.
    void fullImplicitRuns(const Model& m, int r, const std::vector<double>& dts, double fMesh, double meshError) {
        std::vector<double> steps = dts;
        const double dtNear = backwardEulerDtForError(2 * M_PI * fMesh, wRef_, std::max(0.01, 1.2 * meshError));
        if (dtNear > 0 && dtNear < 0.9 * steps.back()) steps.push_back(dtNear);
        for (double dt : steps) {
            const StepOptions opt{Integrator::BackwardEuler, dt};
            char name[160];
            std::snprintf(name, sizeof name, "backward_euler %dx%dx%d dt=%.3g", 10 * r, r, r, dt);
            log(runStaticPoint(ctx_, m, opt, name));
            log(predicted(runFrequencyPoint(ctx_, m, opt, name), opt, fMesh));
        }
        cgFrequencyPoint(m, r, steps.back(), fMesh);
    }

    // Backward Euler's step timed on the mesh, with either solver, and its cost at 1% projected.
    ImplicitProjection projection(const Model& m, int r, double fMesh, double meshError) const {
        ImplicitProjection pr;
        pr.res = r;
        pr.tets = m.elements();
        pr.meshFrequency = fMesh;
        pr.meshError = meshError;
        pr.dt = backwardEulerDtForError(2 * M_PI * fMesh, wRef_, 0.01);
        pr.steps = ctx_.tiny ? 3 : 5;
        const double dtTimed = pr.dt > 0 ? pr.dt : 1e-3;
        pr.directSeconds = backwardEulerStepSeconds(m, dtTimed, pr.steps, ImplicitSolver::Direct).first;
        std::tie(pr.cgSeconds, pr.cgIterations) =
            backwardEulerStepSeconds(m, dtTimed, pr.steps, ImplicitSolver::ConjugateGradient);
        if (pr.dt > 0) pr.cost = pr.stepSeconds() / pr.dt;
        if (!quiet_)
            std::fprintf(stderr,
                         "  backward Euler %dx%dx%d: mesh frequency error %.4f, a step %.4g s (LDL^T) / %.4g s (CG, %d "
                         "iterations), "
                         "dt for 1%%: %.4g s, projected %.4g s/s\n",
                         10 * r, r, r, pr.meshError, pr.directSeconds, pr.cgSeconds, pr.cgIterations, pr.dt, pr.cost);
        return pr;
    }

    // The projection checked where a full run is affordable: backward Euler with CG (the cheaper
    // solve at this dt) at the dt the mode formula gives for 1%.
    void checkProjection(const Model& m, int r, double dt, double fMesh) {
        const BenchPoint p = cgFrequencyPoint(m, r, dt, fMesh);
        // Measured above 1% (the formula's error is a prediction): once more at the dt that
        // brings it to 1%. The error squared is the frequency error's square plus the damping
        // ratio's (modeError); the frequency part barely moves with dt and backward Euler's
        // damping ratio is linear in dt (w dt / 2 for small w dt), so dt scales with the
        // damping ratio, aimed at a total of 0.998% so that the fit's scatter stays below 1%.
        const double freq = std::abs(p.frequencyError), aim = 0.00998;
        if (std::isfinite(p.error) && p.error > 0.01 && freq < aim && p.dampingRatio > 0)
            cgFrequencyPoint(m, r, dt * std::sqrt(aim * aim - freq * freq) / p.dampingRatio, fMesh);
    }

    // Backward Euler solved by CG at dt, its first mode measured (frequency problem only). On the
    // finest mesh the explicit runs at 0.999 of its limit, in double and single precision, take
    // turns with it (pairedCgPoint).
    BenchPoint cgFrequencyPoint(const Model& m, int r, double dt, double f) {
        const StepOptions cg = backwardEulerOptions(dt, ImplicitSolver::ConjugateGradient);
        char name[160];
        std::snprintf(name, sizeof name, "backward_euler cg %dx%dx%d dt=%.3g", 10 * r, r, r, dt);
        if (r == finest_ && dtFinest_ > 0) return pairedCgPoint(m, r, cg, name, f);
        const BenchPoint p = predicted(runFrequencyPoint(ctx_, m, cg, name), cg, f);
        log(p);
        return p;
    }

    // The CG run and the explicit ones taking turns: their cost ratio at equal machine conditions.
    // The explicit points are those of the conforming runs, bitwise (the same steps), and are not
    // logged twice.
    BenchPoint pairedCgPoint(const Model& m, int r, const StepOptions& cg, const std::string& name, double f) {
        std::vector<FrequencyRun> runs;
        runs.emplace_back(ctx_, m, cg, name);
        const StepOptions ex{Integrator::SymplecticEuler, 0.999 * dtFinest_};
        runs.emplace_back(ctx_, m, ex, explicitName("", r, 0.999));
        Model ms = m;
        ms.precision = ForcePrecision::Single;
        runs.emplace_back(ctx_, ms, ex, explicitName("single ", r, 0.999));
        const PairedRuns turns = runPaired(runs, kPairedSlices);
        const BenchPoint p = predicted(turns.points[0], cg, f);
        log(p);
        PairedComparison c;
        c.implicitPoint = p;
        c.slices = kPairedSlices;
        for (size_t k = 1; k < runs.size(); ++k) {
            PairedComparison::Explicit e;
            e.point = turns.points[k];
            e.ratio = turns.costRatio(0, k, 0, kPairedSlices);
            e.firstHalf = turns.costRatio(0, k, 0, kPairedSlices / 2);
            e.secondHalf = turns.costRatio(0, k, kPairedSlices / 2, kPairedSlices);
            e.sliceMin = INFINITY;
            e.sliceMax = 0;
            for (int i = 0; i < kPairedSlices; ++i) {
                const double q = turns.costRatio(0, k, i, i + 1);
                e.sliceMin = std::min(e.sliceMin, q);
                e.sliceMax = std::max(e.sliceMax, q);
            }
            if (!quiet_)
                std::fprintf(
                    stderr,
                    "    taking turns with it: %-34s error %.3e  cost %.4g s/s  ratio %.3g (halves %.3g, %.3g)\n",
                    e.point.config.c_str(), e.point.error, e.point.wallPerSimSecond, e.ratio, e.firstHalf,
                    e.secondHalf);
            c.runs.push_back(e);
        }
        paired_.push_back(c);
        return p;
    }

    const AccuracyContext& ctx_;
    bool quiet_;
    std::vector<ImplicitProjection>& proj_;
    std::vector<PairedComparison>& paired_;
    std::vector<BenchPoint> pts_;
    double wRef_;                // the reference's first bending frequency [rad/s]
    std::vector<double> fMesh_;  // first bending frequency of each mesh of ctx_.res [Hz]
    int finest_;                 // the finest N
    double dtFinest_ = 0;        // exact limit of the finest mirrored bar, set by the explicit runs [s]
};

// The flags as the configurations' context: resolutions, references, sizes.
AccuracyContext accuracyContext(const AccuracyArgs& a, json& refs) {
    AccuracyContext ctx;
    ctx.tiny = a.tiny;
    if (a.tiny)
        ctx.res = {1};
    else if (!a.res.empty())
        ctx.res = a.res;
    else
        for (int r = 1; r <= a.maxRes; ++r) ctx.res.push_back(r);
    std::sort(ctx.res.begin(), ctx.res.end());
    ctx.res.erase(std::unique(ctx.res.begin(), ctx.res.end()), ctx.res.end());
    ctx.maxRes = ctx.res.back();
    ctx.implicitMaxRes = a.implicitMaxRes;
    ctx.cgMaxRes = a.cgMaxRes;
    ctx.quiet = a.json;
    ctx.references = &refs;
    if (a.tiny) {
        ctx.bar.staticTime = 0.2;
        ctx.bar.frequencyTime = 0.5;
    }
    // Converged references: Richardson extrapolation of the two finest reference meshes
    // (linear tets converge as h^2); the coarser pair shows how well converged they are.
    std::vector<int> levels = a.tiny                ? std::vector<int>{2, 4}
                              : a.refLevels.empty() ? std::vector<int>{2, 4, 8}
                                                    : a.refLevels;
    std::sort(levels.begin(), levels.end());
    levels.erase(std::unique(levels.begin(), levels.end()), levels.end());
    if (levels.size() < 2) throw InputError("--ref-levels", 0, "needs at least two different levels");
    const BarReferences br = barReferences(
        levels, [&](int r) { return cantileverModel(ctx.bar, r, ElementModel::Corotational, BoxSplit::Mirrored); });
    ctx.tipReference = br.tip;
    ctx.frequencyReference = br.frequency;
    // Euler-Bernoulli with Timoshenko's shear term (kappa = 5/6) and the first bending frequency.
    const auto& bar = ctx.bar;
    const double E = bar.material.E, G = E / (2 * (1 + bar.material.nu)), A = bar.h * bar.h, I = A * A / 12;
    const double q = bar.material.rho * 9.81 * A, L = bar.L;
    const double beamTip = -(q * std::pow(L, 4) / (8 * E * I) + q * L * L / (2 * (5.0 / 6.0) * G * A));
    const double beamFreq = 1.8751 * 1.8751 / (2 * M_PI * L * L) * std::sqrt(E * I / (bar.material.rho * A));
    // a reference, the values converging to it and beam theory's value beside it
    auto entry = [&](double reference, const auto& values, double order, double beam) {
        return json{{"reference", reference}, {"levels", levels},
                    {"values", values},       {"observed_order", std::isfinite(order) ? json(order) : json(nullptr)},
                    {"beam_theory", beam},    {"reference_over_beam", reference / beam}};
    };
    refs["cantilever_static"] = entry(ctx.tipReference, br.tips, br.tipOrder, beamTip);
    refs["cantilever_frequency"] = entry(ctx.frequencyReference, br.freqs, br.frequencyOrder, beamFreq);
    if (!a.json)
        std::fprintf(stderr,
                     "references: tip %.6g m (beam theory %.6g m), frequency %.6g Hz (Euler-Bernoulli %.6g Hz)\n",
                     ctx.tipReference, beamTip, ctx.frequencyReference, beamFreq);
    return ctx;
}

// The measured points: the built-in cantilever runs and every selected registered configuration.
std::vector<BenchPoint> measureAccuracy(const AccuracyArgs& a, json& refs, std::vector<ImplicitProjection>& proj,
                                        std::vector<PairedComparison>& paired) {
    // Backward Euler's factorisation (Eigen's simplicial LDL^T) runs on one core whatever
    // this says; the explicit force stage on all of these.
    setThreads(a.threads);
    const AccuracyContext ctx = accuracyContext(a, refs);
    std::vector<BenchPoint> pts;
    if (selected(a, "cantilever")) pts = CantileverRuns(ctx, a.json, proj, paired).run();
    for (auto& [name, fn] : configs()) {
        if (!selected(a, name)) continue;
        auto more = fn(ctx);
        pts.insert(pts.end(), more.begin(), more.end());
    }
    return pts;
}

// The points as JSON.
json pointsJson(const std::vector<BenchPoint>& pts) {
    json points = json::array();
    for (const auto& p : pts) {
        json q = {{"problem", p.problem},
                  {"config", p.config},
                  {"error", jsonNumber(p.error)},
                  {"wall_per_sim_second", p.wallPerSimSecond},
                  {"dt", p.dt},
                  {"scheme", p.explicitScheme ? "explicit" : "implicit"},
                  {"pareto", p.pareto}};
        if (std::isfinite(p.frequencyError)) q["frequency_error"] = p.frequencyError;
        if (std::isfinite(p.dampingRatio)) q["damping_ratio"] = p.dampingRatio;
        if (std::isfinite(p.predictedError)) q["predicted_error"] = p.predictedError;
        points.push_back(q);
    }
    return points;
}

// Per problem: the cost of 1% error explicit and implicit, and at the finest error both reach.
json summaryJson(const std::vector<BenchPoint>& pts) {
    json summary = json::object();
    for (const auto& p : pts) {
        if (summary.contains(p.problem)) continue;
        const double ex = costAtError(pts, p.problem, 0.01, true), im = costAtError(pts, p.problem, 0.01, false);
        // When 1% is out of reach: the finest error both kinds reach, and their costs there.
        double minEx = INFINITY, minIm = INFINITY;
        for (const auto& q : pts)
            if (q.problem == p.problem)
                (q.explicitScheme ? minEx : minIm) = std::min(q.explicitScheme ? minEx : minIm, q.error);
        const double common = std::max(minEx, minIm);
        const double exC = costAtError(pts, p.problem, common, true), imC = costAtError(pts, p.problem, common, false);
        summary[p.problem] = {{"best_explicit_cost_at_1pct", jsonNumber(ex)},
                              {"implicit_cost_at_1pct", jsonNumber(im)},
                              {"speedup_at_1pct", ex > 0 && im > 0 ? json(im / ex) : json(nullptr)},
                              {"best_explicit_error", jsonNumber(minEx)},
                              {"best_implicit_error", jsonNumber(minIm)},
                              {"common_error", jsonNumber(common)},
                              {"explicit_cost_at_common_error", jsonNumber(exC)},
                              {"implicit_cost_at_common_error", jsonNumber(imC)}};
    }
    return summary;
}

// The implicit reference where it is too dear to run: measured step, projected steps.
void addImplicitProjection(const std::vector<ImplicitProjection>& proj, const std::vector<BenchPoint>& pts, json& j) {
    j["implicit_projection"] = json::array();
    const ImplicitProjection* best = nullptr;
    for (const auto& pr : proj) {
        j["implicit_projection"].push_back({{"res", pr.res},
                                            {"tets", pr.tets},
                                            {"mesh_frequency", pr.meshFrequency},
                                            {"mesh_error", pr.meshError},
                                            {"dt_at_1pct", jsonNumber(pr.dt > 0 ? pr.dt : -1)},
                                            {"step_seconds", pr.stepSeconds()},
                                            {"solver", pr.solver()},
                                            {"step_seconds_direct", pr.directSeconds},
                                            {"step_seconds_cg", pr.cgSeconds},
                                            {"cg_iterations", pr.cgIterations},
                                            {"steps_timed", pr.steps},
                                            {"cost_at_1pct", jsonNumber(std::isfinite(pr.cost) ? pr.cost : -1)}});
        if (std::isfinite(pr.cost) && (!best || pr.cost < best->cost)) best = &pr;
    }
    if (j["summary"].contains("cantilever_frequency")) {
        auto& s = j["summary"]["cantilever_frequency"];
        const double ex = costAtError(pts, "cantilever_frequency", 0.01, true);
        s["implicit_cost_at_1pct_projected"] = best ? json(best->cost) : json(nullptr);
        s["implicit_projected_res"] = best ? json(best->res) : json(nullptr);
        s["speedup_at_1pct_projected"] = best && ex > 0 ? json(best->cost / ex) : json(nullptr);
    }
}

// Explicit runs that took turns with an implicit one: their cost ratio at equal machine
// conditions. The summary's: the cheapest implicit point at 1% and its cheapest explicit one.
void addPaired(const std::vector<PairedComparison>& paired, json& j) {
    j["paired"] = json::array();
    const PairedComparison* best = nullptr;
    const PairedComparison::Explicit* bestEx = nullptr;
    for (const auto& c : paired) {
        json runs = json::array();
        for (const auto& e : c.runs)
            runs.push_back({{"config", e.point.config},
                            {"error", jsonNumber(e.point.error)},
                            {"cost", e.point.wallPerSimSecond},
                            {"ratio", e.ratio},
                            {"ratio_first_half", e.firstHalf},
                            {"ratio_second_half", e.secondHalf},
                            {"slice_ratio_min", e.sliceMin},
                            {"slice_ratio_max", e.sliceMax}});
        j["paired"].push_back({{"problem", c.implicitPoint.problem},
                               {"implicit", c.implicitPoint.config},
                               {"implicit_error", jsonNumber(c.implicitPoint.error)},
                               {"implicit_cost", c.implicitPoint.wallPerSimSecond},
                               {"slices", c.slices},
                               {"explicit", runs}});
        if (!(c.implicitPoint.error <= 0.01) ||
            (best && best->implicitPoint.wallPerSimSecond <= c.implicitPoint.wallPerSimSecond))
            continue;
        const PairedComparison::Explicit* cheapest = nullptr;
        for (const auto& e : c.runs)
            if (e.point.error <= 0.01 && (!cheapest || e.point.wallPerSimSecond < cheapest->point.wallPerSimSecond))
                cheapest = &e;
        if (cheapest) {
            best = &c;
            bestEx = cheapest;
        }
    }
    const std::string problem = paired.front().implicitPoint.problem;
    if (j["summary"].contains(problem)) {
        auto& s = j["summary"][problem];
        s["speedup_at_1pct_paired"] = bestEx ? json(bestEx->ratio) : json(nullptr);
        s["paired_explicit"] = bestEx ? json(bestEx->point.config) : json(nullptr);
        s["paired_implicit"] = best ? json(best->implicitPoint.config) : json(nullptr);
    }
}

// The text report: the points, the projection, the paired runs and the summary.
void printAccuracy(const std::vector<BenchPoint>& pts, const std::vector<ImplicitProjection>& proj,
                   const std::vector<PairedComparison>& paired, const json& summary) {
    std::printf("%-26s %-42s %12s %14s %12s %6s %11s %11s %11s\n", "problem", "config", "error", "wall/sim [s/s]",
                "dt [s]", "pareto", "freq err", "damping", "predicted");
    auto opt = [](double v) {
        char b[32];
        if (std::isfinite(v))
            std::snprintf(b, sizeof b, "%11.3e", v);
        else
            std::snprintf(b, sizeof b, "%11s", "");
        return std::string(b);
    };
    for (const auto& p : pts)
        std::printf("%-26s %-42s %12.4e %14.5g %12.4g %6s %s %s %s\n", p.problem.c_str(), p.config.c_str(), p.error,
                    p.wallPerSimSecond, p.dt, p.pareto ? "*" : "", opt(p.frequencyError).c_str(),
                    opt(p.dampingRatio).c_str(), opt(p.predictedError).c_str());
    if (!proj.empty()) {
        std::printf(
            "\nbackward Euler at 1%% on cantilever_frequency, projected: its step timed on each mesh, over the dt at\n"
            "which its first mode is 1%% off (mesh error from Lanczos):\n");
        std::printf("  %-12s %8s %11s %13s %10s %8s %12s %14s\n", "mesh", "tets", "mesh error", "LDL^T [s]", "CG [s]",
                    "CG its", "dt 1% [s]", "cost [s/s]");
        for (const auto& pr : proj) {
            char mesh[32];
            std::snprintf(mesh, sizeof mesh, "%dx%dx%d", 10 * pr.res, pr.res, pr.res);
            std::printf("  %-12s %8ld %11.4f %13.4g %10.4g %8d %12s %14s\n", mesh, pr.tets, pr.meshError,
                        pr.directSeconds, pr.cgSeconds, pr.cgIterations,
                        pr.dt > 0 ? std::to_string(pr.dt).c_str() : "-",
                        std::isfinite(pr.cost) ? std::to_string(pr.cost).c_str() : "-");
        }
    }
    if (!paired.empty()) {
        std::printf("\nexplicit runs taking turns with an implicit one (%d slices of equal simulated time; ratio = "
                    "implicit cost /\n"
                    "explicit cost, over the run, its two halves, and the range of single slices):\n",
                    paired.front().slices);
        for (const auto& c : paired) {
            std::printf("  %s: error %.4e, %.5g s/s\n", c.implicitPoint.config.c_str(), c.implicitPoint.error,
                        c.implicitPoint.wallPerSimSecond);
            for (const auto& e : c.runs)
                std::printf("    %-38s error %.4e  %9.5g s/s  ratio %6.3f  halves %6.3f %6.3f  slices %6.3f .. %6.3f\n",
                            e.point.config.c_str(), e.point.error, e.point.wallPerSimSecond, e.ratio, e.firstHalf,
                            e.secondHalf, e.sliceMin, e.sliceMax);
        }
    }
    std::printf("\ncost at 1%% error (wall s per simulated s; - = not reached):\n");
    for (auto& [problem, s] : summary.items()) {
        auto show = [](const json& v) { return v.is_null() ? std::string("-") : std::to_string(v.get<double>()); };
        std::printf(
            "  %-22s explicit %s  implicit %s;  at the finest error both reach (%s): explicit %s  implicit %s\n",
            problem.c_str(), show(s["best_explicit_cost_at_1pct"]).c_str(), show(s["implicit_cost_at_1pct"]).c_str(),
            show(s["common_error"]).c_str(), show(s["explicit_cost_at_common_error"]).c_str(),
            show(s["implicit_cost_at_common_error"]).c_str());
        if (s.contains("speedup_at_1pct_paired") && !s["speedup_at_1pct_paired"].is_null())
            std::printf("  %-22s taking turns at 1%%: %s cheaper by %.3fx than %s\n", "",
                        s["paired_explicit"].get<std::string>().c_str(), s["speedup_at_1pct_paired"].get<double>(),
                        s["paired_implicit"].get<std::string>().c_str());
    }
}

int runAccuracy(const AccuracyArgs& a) {
    if (!a.plot.empty() && !haveGnuplot()) {
        std::fprintf(stderr, "error: --plot needs gnuplot, which is not installed (Debian package gnuplot-nox)\n");
        return 2;
    }
    const json machine = machineJson();
    std::vector<ImplicitProjection> proj;
    std::vector<PairedComparison> paired;
    json refs = json::object();
    std::vector<BenchPoint> pts = a.from.empty() ? measureAccuracy(a, refs, proj, paired) : readPointsCsv(a.from);
    markPareto(pts);

    json j;
    j["points"] = pointsJson(pts);
    j["summary"] = summaryJson(pts);
    if (!proj.empty()) addImplicitProjection(proj, pts, j);
    if (!paired.empty()) addPaired(paired, j);
    if (!refs.empty()) j["references"] = refs;
    if (a.from.empty()) j["threads"] = threads();
    if (!a.csv.empty()) writeFileAtomic(a.csv, pointsCsv(pts));
    if (!a.plot.empty()) plotPoints(pts, a.plot);
    if (a.json) {
        if (a.from.empty())
            printResult(j, machine);  // measured here: the machine and its load with the times
        else
            printJson(j);
        return 0;
    }
    printAccuracy(pts, proj, paired, j["summary"]);
    return 0;
}

void accuracyOptions(CLI::App& c, AccuracyArgs& a) {
    jsonFlag(c, a.json,
             "{points: [{problem, config, error, wall_per_sim_second, dt, scheme, pareto}], "
             "summary: {problem: {best_explicit_cost_at_1pct, implicit_cost_at_1pct, common_error, "
             "speedup_at_1pct_paired, ...}}, "
             "paired: [{implicit, implicit_cost, slices, explicit: [{config, cost, ratio, ...}]}] (the explicit "
             "runs that took turns with the CG runs on the finest bar), references}; error is null for a run "
             "that diverged or gave no frequency, "
             "a cost is null when no point reaches the error; with a run (not --from)",
             true);
    csvOption(c, a.csv, "points");
    plotOption(c, a.plot, "error against cost with the Pareto front");
    c.add_option("--from", a.from,
                 "Take the points from a CSV "
                 "(problem,config,error,wall_per_sim_second,dt[,scheme,pareto,frequency_error,damping_ratio,"
                 "predicted_error]) "
                 "instead of running");
    c.add_option("--max-res", a.maxRes, "Finest explicit mesh: 10N x N x N cubes")
        ->check(CLI::Range(1, 8))
        ->capture_default_str();
    c.add_option("--res", a.res,
                 "Cantilever meshes N to run instead of 1 .. max-res, comma-separated (10N x N x N cubes)")
        ->delimiter(',')
        ->check(CLI::Range(1, 24));
    c.add_option("--ref-levels", a.refLevels,
                 "Reference meshes N, comma-separated, at least two: Richardson (h^2) from the "
                 "two finest [default 2,4,8]")
        ->delimiter(',')
        ->check(CLI::Range(1, 24));
    c.add_option("--implicit-max-res", a.implicitMaxRes,
                 "Run backward Euler in full up to this N; beyond it only its step "
                 "is timed (its cost at 1% projected)")
        ->check(CLI::Range(0, 24))
        ->capture_default_str();
    c.add_option("--cg-max-res", a.cgMaxRes,
                 "Beyond --implicit-max-res and up to this N, run backward Euler with CG "
                 "in full at the dt its mode formula gives for 1% (the projection, measured)")
        ->check(CLI::Range(0, 24))
        ->capture_default_str();
    tinyFlag(c, a.tiny, "coarse meshes, short runs");
    threadsOption(c, a.threads,
                  "Worker threads of the explicit runs and of CG's matrix products (Eigen's, "
                  "OpenMP) (0 = all cores; the LDL^T factorisation is sequential)",
                  0)
        ->capture_default_str();
    c.add_option("--only", a.only, "Run only these groups, comma-separated: cantilever, mi, notch-lumping, liver")
        ->delimiter(',')
        ->check(CLI::IsMember({"cantilever", "mi", "notch-lumping", "liver"}));
}

}  // namespace

void addAccuracyBench() {
    addSubcommand("accuracy",
                  "Error against wall time per simulated second: the cantilever (static tip "
                  "deflection, first bending frequency) on conforming and MI meshes, the notched "
                  "cantilever per XFEM lumping option, the liver sagging under gravity",
                  accuracyOptions, runAccuracy);
}

}  // namespace cutsim::bench
