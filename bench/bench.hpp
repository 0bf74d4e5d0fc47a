// What the files of `cutsim bench` share: accuracy against cost, stability sweeps, step throughput
// and per-scene cost. Other files extend it by one call each: addAccuracyConfig() adds
// configurations to `bench accuracy` (e.g. MI background meshes, lumping after cuts),
// addBenchSubcommand() adds a whole subcommand (bench/options.hpp: addSubcommand, with the options
// and result files the subcommands share). Both are listed in registerBenchExtensions() in
// bench.cpp; the program adds the command with addBenchCommand() (bench/command.hpp).
#pragma once

#include "fem/integrate.hpp"
#include "fem/model.hpp"
#include "bench/oscillation.hpp"
#include "fem/state.hpp"
#include "mesh/generate.hpp"

#include <nlohmann/json_fwd.hpp>

#include <cmath>
#include <functional>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace cutsim::bench {

// One configuration's result on one reference problem.
struct BenchPoint {
    std::string problem;          // cantilever_static | cantilever_frequency | ...
    std::string config;           // e.g. "conforming 40x4x4 f=0.9", "backward_euler 40x4x4 dt=0.01"
    double error = 0;             // relative error against the problem's reference [-]
    double wallPerSimSecond = 0;  // wall time of the stepping loop / simulated time [s/s]
    double dt = 0;                // time step used [s]
    bool explicitScheme = true;   // false for the implicit reference
    bool pareto = false;          // on the error-cost Pareto front of its problem
    // Frequency problems: the two parts of the error (NaN elsewhere), and the error the integrator's
    // mode formula predicts from the mesh's own first frequency (NaN where no formula applies).
    double frequencyError = NAN;  // (f - f_ref) / f_ref, signed [-]
    double dampingRatio = NAN;    // decay rate of the tip's oscillation / omega_ref [-]
    double predictedError = NAN;  // [-]
};

// Marks, per problem, the points no other point beats in both error and cost (ties: not beaten).
void markPareto(std::vector<BenchPoint>& points);
// Smallest cost among the problem's points with error <= maxError, explicit or implicit ones;
// negative when none reaches it.
double costAtError(const std::vector<BenchPoint>& points, const std::string& problem, double maxError,
                   bool explicitScheme);

// The cantilever of the accuracy problems: length L along x, square section h, clamped at x = 0,
// gravity -z. Meshes of nyz cubes through the section and 10 nyz along the length.
struct Cantilever {
    double L = 1.0, h = 0.1;            // [m]
    Material material{1e8, 0.3, 1000};  // [Pa, -, kg/m^3]
    double damping = 60;                // mass damping of the static runs, near critical for mode 1 [1/s]
    double staticTime = 0.6;            // simulated time of a static run [s]
    double frequencyTime = 1.0;         // simulated time of an undamped frequency run [s]
};
// The bar meshed as 10 nyz x nyz x nyz cubes, clamped at x = 0, gravity along -z. The accuracy
// bench meshes it Mirrored (no skew bending axes); elsewhere it is the plain Kuhn split.
Model cantileverModel(const Cantilever& c, int nyz, ElementModel em = ElementModel::Corotational,
                      BoxSplit split = BoxSplit::Kuhn);
// The SOFA liver as the demo and liver_cuts scenes set it up (inches to m, E 30 kPa, fixed behind
// z = -0.028 m, gravity -y), refined `levels` times, with mass damping (cuts.cpp).
Model liverModel(const TetMesh& inches, int levels, double damping);
// Static equilibrium under gravity by backward Euler at a long step; *steps gets its steps.
Eigen::Matrix3Xd liverEquilibrium(const Model& m0, int* steps);

// Mean z displacement of the nodes at x = L [m].
double tipDeflection(const Model& m, const Eigen::Matrix3Xd& x);

// What a configuration needs to compute its points: the problem and its converged references.
struct AccuracyContext {
    Cantilever bar;
    double tipReference = 0;               // converged static tip deflection (negative, along -z) [m]
    double frequencyReference = 0;         // converged first bending frequency (z) [Hz]
    bool tiny = false;                     // test size: small meshes, short runs
    int maxRes = 4;                        // finest explicit cantilever: 10N x N x N cubes
    std::vector<int> res;                  // the cantilever resolutions N to run (ascending; maxRes is the last)
    int implicitMaxRes = 4;                // backward Euler runs in full up to this N; beyond, its step is timed
    int cgMaxRes = 0;                      // and beyond that, up to this N, its CG solve runs in full at its 1% dt
    bool quiet = false;                    // no progress lines on stderr
    nlohmann::json* references = nullptr;  // configurations add their problems' references here
};

// A problem's measured quantity and converged reference. Default: the cantilever's (tipDeflection,
// ctx.tipReference or ctx.frequencyReference, problems cantilever_static / cantilever_frequency).
using TipFn = std::function<double(const Model&, const Eigen::Matrix3Xd&)>;
struct TipProbe {
    std::string problem;   // problem name; empty: the cantilever's
    double reference = 0;  // converged tip deflection [m] or frequency [Hz]
    TipFn tip;             // tip deflection of positions x [m]; null: tipDeflection
};

// Runs model from rest under gravity for bar.staticTime with the model's damping and returns the
// point (error of the final tip deflection against the reference).
BenchPoint runStaticPoint(const AccuracyContext& ctx, const Model& m, const StepOptions& opt, const std::string& config,
                          const TipProbe& probe = {});
// Runs model from rest under gravity without damping for bar.frequencyTime and returns the point.
// Its error is that of the tip's first mode as a complex frequency s = -decay + i omega (both
// measured by fitOscillation) against i omega_ref: |s - i omega_ref| / omega_ref. A frequency alone would
// let an integrator's damping go unseen, and its period error cancel the mesh's stiffness.
BenchPoint runFrequencyPoint(const AccuracyContext& ctx, const Model& m, const StepOptions& opt,
                             const std::string& config, const TipProbe& probe = {});
// A frequency run (as runFrequencyPoint) advanced in slices, so that runs can take turns on the
// machine (runPaired): the same steps, hence the same point, in any slicing.
class FrequencyRun {
public:
    FrequencyRun(const AccuracyContext& ctx, const Model& m, const StepOptions& opt, std::string config,
                 TipProbe probe = {});
    ~FrequencyRun();
    FrequencyRun(FrequencyRun&&) noexcept;
    // Steps on while the simulated time is below until (INFINITY: to the run's end) and the run has
    // neither ended nor diverged; returns the wall time of these steps [s].
    double advance(double until);
    // Simulated time of the steps so far [s].
    double time() const { return s_.time; }
    // The point of the steps so far (its cost: their wall time over their simulated time).
    BenchPoint point() const;
    const AccuracyContext& context() const { return *ctx_; }

private:
    const AccuracyContext* ctx_;
    Model m_;
    StepOptions opt_;
    std::string config_;
    TipProbe probe_;
    State s_;
    Stepper st_;
    long n_ = 0, k_ = 0;
    std::vector<double> t_, y_;
    double wall_ = 0;
    bool diverged_ = false;
};

// Runs that took turns: each run's point, its simulated time, and its wall time in each slice [s].
struct PairedRuns {
    std::vector<BenchPoint> points;
    std::vector<double> simTime;                 // [run]
    std::vector<std::vector<double>> sliceWall;  // [run][slice]
    // Cost of run a over cost of run b (wall per simulated second) in slices [from, to): their
    // walls there, over the whole runs' simulated times, so that the ratio of a part and of the
    // whole differ by the walls alone.
    double costRatio(size_t a, size_t b, int from, int to) const;
};
// Runs all of runs to their end in `slices` turns of equal simulated time (bar.frequencyTime /
// slices), the order reversed every other turn. A slow spell of the machine then falls on the
// runs' turns of that time, not on one run alone, which costs taken minutes apart cannot avoid.
PairedRuns runPaired(std::vector<FrequencyRun>& runs, int slices);

// Linear static tip deflection, K u = M g over the free DOFs (small-displacement limit of the
// corotational model) [m]; tip: as TipProbe (null: tipDeflection).
double linearStaticTip(const Model& m, const TipFn& tip = {});
// First bending frequency in z with the lumped mass (the low mode whose tip face moves most along
// z, shift-invert Lanczos) [Hz].
double firstBendingFrequency(const Model& m);
// Richardson extrapolation of values on meshes h and h / ratio for an O(h^2) method.
double richardson(double coarse, double fine, double ratio = 2);
// The convergence order p that the last three of values on meshes of `levels` elements across
// show, from (v1 - v2) / (v2 - v3) = (n1^-p - n2^-p) / (n2^-p - n3^-p); NaN with fewer than three
// levels or when they do not converge monotonically at an order between 0.1 and 8.
double observedOrder(const std::vector<int>& levels, const std::vector<double>& values);
// Converged references of a bar family: the linear static tip and the first bending frequency on
// the model of each level (ascending), extrapolated (h^2) from the two finest.
struct BarReferences {
    std::vector<double> tips, freqs;              // per level [m], [Hz]
    double tip = 0, frequency = 0;                // Richardson from the two finest [m], [Hz]
    double tipOrder = NAN, frequencyOrder = NAN;  // observedOrder of the last three levels
};
BarReferences barReferences(const std::vector<int>& levels, const std::function<Model(int)>& model);
using AccuracyConfig = std::function<std::vector<BenchPoint>(const AccuracyContext&)>;
// Adds a configuration to `bench accuracy` (its points join the table, CSV, plot and summary).
void addAccuracyConfig(const std::string& name, AccuracyConfig fn);
// Adds a subcommand under `cutsim bench`; setup receives the bench command and adds to it.
void addBenchSubcommand(std::function<void(CLI::App& bench)> setup);

// Models after XFEM cuts for the stability sweep: the notched cantilever 20x2x2 and the liver
// after the thesis's four planes (sec. 5.2), one per lumping option (cuts.cpp).
struct AfterCutModel {
    std::string mesh;     // e.g. "cantilever 20x2x2, notch"
    std::string lumping;  // row_sum | weighted_diagonal | enrichment
    Model model;          // after the cuts
    double dtUncut = 0;   // exact step before the cuts [s]
    int crossed = 0;      // elements the cuts went through
};
std::vector<AfterCutModel> afterCutModels(bool tiny);

// Accuracy configurations of cuts.cpp: MI background meshes, the notched cantilever
// (XFEM with each lumping option against the same geometry meshed conformingly), the liver sag.
void addCutAccuracyConfigs();

// `bench mi-bar` (mibar.cpp): Table 6.1, MI against subdivision and remeshing.
void addMiBarBench();
void addAccuracyBench();   // accuracy.cpp
void addStabilityBench();  // stability.cpp
void addStepCostBench();   // step.cpp
void addContactBench();    // contact.cpp
void addHapticBench();     // haptic.cpp
void addCaptureBench();    // capture.cpp
void addImproveBench();    // improve.cpp
void addCutStepBench();    // cutstep.cpp
void addScaleBench();      // scale.cpp
void addThreadsBench();    // threads.cpp

// Runs a bench subcommand: InputError exits 2, any other failure 1, each with "error: " on stderr.
int benchGuarded(const std::function<int()>& f);

// Plots: gnuplot on PATH (Debian package gnuplot-nox); a fresh folder for a plot's data files;
// the script `body` run with `terminal` into `out` (a PNG, replaced only when gnuplot succeeds),
// the folder removed after.
bool haveGnuplot();
std::string plotDataDir(const std::string& tag);
void runGnuplot(const std::string& dir, const std::string& terminal, const std::string& body, const std::string& out);
// A measured value for JSON: null when it is not a finite non-negative number (a run that gave none).
nlohmann::json jsonNumber(double v);

}  // namespace cutsim::bench
