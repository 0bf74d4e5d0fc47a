// `cutsim bench stability`: the largest stable fraction of the exact step per integrator and scheme,
// after XFEM cuts per lumping, over random cut sequences, and the energy drift of a long run.
#include "bench/bench.hpp"
#include "bench/machine.hpp"
#include "bench/options.hpp"
#include "app/commands.hpp"
#include "sim/simulation.hpp"
#include "sim/scene.hpp"
#include "bench/random_cuts.hpp"
#include "fem/forces.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "timestep/timestep.hpp"
#include "timestep/modes.hpp"
#include "util/stopwatch.hpp"

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace cutsim::bench {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// ---- bench stability ----

struct StabilityArgs {
    bool json = false, tiny = false;
    int steps = 2000;
    int cutRuns = 150;   // random cut sequences per object
    int cutSteps = 300;  // steps between two cuts of a sequence
};

// The sweep's meshes: the clamped cantilever 20x2x2 and, when present, the liver mesh.
struct SweepModel {
    std::string name;
    Model model;
};

// Fraction grid: 0.5 .. 1.2 step 0.05, finer near 1 (to 0.1%: the limit is exact, so a plain
// scheme should be stable to just below 1.0).
std::vector<double> fractionGrid(double top) {
    std::vector<double> f;
    for (int k = 0; k <= 14; ++k) f.push_back(0.5 + 0.05 * k);
    for (double x : {0.97, 0.98, 0.99, 0.995, 0.999, 1.001, 1.005, 1.01, 1.02}) f.push_back(x);
    for (double x = 1.3; x <= top + 1e-9; x += 0.1) f.push_back(x);
    for (double& x : f) x = std::round(x * 1000) / 1000;  // exact decimals in the output
    std::sort(f.begin(), f.end());
    f.erase(std::unique(f.begin(), f.end(), [](double a, double b) { return std::abs(a - b) < 1e-9; }), f.end());
    return f;
}

// Runs steps from a perturbed state without gravity; stable when the energy (kinetic + elastic)
// stays below 1e3 times its start and everything stays finite.
bool stableRun(const Model& m0, const StepOptions& opt, int steps, double* growth) {
    Model m = m0;
    m.gravity.setZero();
    m.massDamping = 0;
    State s = makeState(m);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    const double vScale = 1e-3 * m.material.pWaveSpeed() * 1e-3;  // small: the linear regime
    for (int i = 0; i < m.nodes(); ++i)
        if (m.invMass(i) > 0) s.v.col(i) << vScale * u(rng), vScale * u(rng), vScale * u(rng);
    const double e0 = kineticEnergy(m, s);
    Stepper st;
    double emax = e0;
    for (int k = 0; k < steps; ++k) {
        st.step(m, s, opt);
        if (s.flags.nonFinite) {
            *growth = INFINITY;
            return false;
        }
        if (k % 50 == 49 || k == steps - 1) {
            const double e = kineticEnergy(m, s) + elasticEnergy(m, s);
            emax = std::max(emax, e);
            if (!(e < 1e3 * e0)) {
                *growth = e / e0;
                return false;
            }
        }
    }
    *growth = emax / e0;
    return true;
}

// The sweep's meshes: a single tet (--tiny) or the cantilever, and the liver when present.
std::vector<SweepModel> sweepModels(bool tiny) {
    std::vector<SweepModel> models;
    Cantilever bar;
    models.push_back({tiny ? "single tet" : "cantilever 20x2x2", Model{}});
    if (tiny) {
        TetMesh t;
        t.X.resize(3, 4);
        t.X << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
        t.tets.resize(4, 1);
        t.tets << 0, 1, 2, 3;
        t.source = "single tet";
        models[0].model = buildModel(t, bar.material);
    } else {
        models[0].model = cantileverModel(bar, 2);
        const std::string liver = std::string(CUTSIM_DATA_DIR) + "/tet/sofa_liver.msh";
        if (fs::exists(liver)) {
            Model m = buildModel(readTetMesh(liver, ReadOptions{}), Material{});
            models.push_back({"liver (sofa_liver.msh)", std::move(m)});
        }
    }
    return models;
}

// Section 1: the largest stable fraction of the exact step per mesh, integrator and scheme.
void sweepSchemes(const std::vector<SweepModel>& models, int steps, bool quiet, json& j) {
    // alpha_e: eq. 3.16 as written, which puts each damped element exactly at its own limit;
    // alpha_e_0.95: the same with a 5% margin on the element steps (dt_e -> 0.95 dt_e).
    struct Scheme {
        Integrator integrator;
        double margin;
    };
    const std::vector<Scheme> schemes = {{Integrator::SymplecticEuler, 0},
                                         {Integrator::CentralDifference, 0},
                                         {Integrator::Newmark, 0},
                                         {Integrator::SymplecticEuler, 1.0},
                                         {Integrator::SymplecticEuler, 0.95}};
    j["sweeps"] = json::array();
    if (!quiet) std::printf("%-26s %-22s %-9s %18s\n", "mesh", "integrator", "scheme", "largest stable f");
    for (const auto& sm : models) {
        const Model& m = sm.model;
        const double dtExact = exactCriticalDt(m).dt;
        const Eigen::VectorXd r1r = estimateElements(m).r1r;
        for (const auto& sc : schemes) {
            const bool damped = sc.margin > 0;
            const auto grid = fractionGrid(damped ? 3.0 : 1.2);
            json runs = json::array();
            double largest = 0;
            bool allBelow = true;
            for (double f : grid) {
                StepOptions opt{sc.integrator, f * dtExact};
                Eigen::VectorXd alpha;
                if (damped) {
                    alpha = elementAlpha(sc.margin * r1r, opt.dt);
                    opt.alphaElem = &alpha;
                }
                double growth = 0;
                const bool ok = stableRun(m, opt, steps, &growth);
                runs.push_back({{"fraction", f}, {"stable", ok}, {"energy_growth", jsonNumber(growth)}});
                if (ok && allBelow) largest = f;
                if (!ok) allBelow = false;
            }
            const std::string scheme = !damped ? "plain" : sc.margin == 1.0 ? "alpha_e" : "alpha_e_0.95";
            j["sweeps"].push_back({{"mesh", sm.name},
                                   {"tets", m.elements()},
                                   {"dt_exact", dtExact},
                                   {"dt_r1r_min_over_exact", r1r.minCoeff() / dtExact},
                                   {"dt_r1r_max_over_exact", r1r.maxCoeff() / dtExact},
                                   {"integrator", integratorName(sc.integrator)},
                                   {"scheme", scheme},
                                   {"largest_stable_fraction", largest},
                                   {"runs", runs}});
            if (!quiet)
                std::printf("%-26s %-22s %-9s %18.3f\n", sm.name.c_str(), integratorName(sc.integrator), scheme.c_str(),
                            largest);
        }
    }
}

// Section 2: after XFEM cuts, the same sweep (plain symplectic Euler) relative to the exact limit
// of the cut model, one model per lumping option.
void sweepAfterCuts(bool tiny, int steps, bool quiet, json& j) {
    j["after_cuts"] = json::array();
    if (!quiet)
        std::printf("\nafter cuts (symplectic Euler, plain; fractions of the cut model's exact limit)\n%-26s %-18s %8s "
                    "%14s %18s\n",
                    "mesh", "lumping", "crossed", "dt cut/uncut", "largest stable f");
    for (AfterCutModel& ac : afterCutModels(tiny)) {
        // Plain: without the damping of the light control points (Model::lightNodes), which is
        // what sets the limit of a cut model and which lets it run past that limit.
        ac.model.lightNodes.clear();
        const double dtExact = exactCriticalDt(ac.model).dt;
        json runs = json::array();
        double largest = 0;
        bool allBelow = true;
        for (double f : fractionGrid(1.2)) {
            double growth = 0;
            const bool ok = stableRun(ac.model, StepOptions{Integrator::SymplecticEuler, f * dtExact}, steps, &growth);
            runs.push_back({{"fraction", f}, {"stable", ok}, {"energy_growth", jsonNumber(growth)}});
            if (ok && allBelow) largest = f;
            if (!ok) allBelow = false;
        }
        j["after_cuts"].push_back({{"mesh", ac.mesh},
                                   {"lumping", ac.lumping},
                                   {"crossed", ac.crossed},
                                   {"tets", ac.model.elements()},
                                   {"dt_uncut", ac.dtUncut},
                                   {"dt_exact", dtExact},
                                   {"dt_ratio", dtExact / ac.dtUncut},
                                   {"integrator", "symplectic_euler"},
                                   {"largest_stable_fraction", largest},
                                   {"runs", runs}});
        if (!quiet)
            std::printf("%-26s %-18s %8d %14.4f %18.3f\n", ac.mesh.c_str(), ac.lumping.c_str(), ac.crossed,
                        dtExact / ac.dtUncut, largest);
    }
}

// Section 3: random cut sequences (the stress test of cutting, short): 1-4 random planes per run,
// steps at 0.9 of the current exact limit between cuts; a failure is a non-finite value or a node
// faster than kBlowUpSpeed.
void randomCutSequences(const StabilityArgs& a, json& j) {
    j["random_cuts"] = json::array();
    if (a.cutRuns <= 0) return;
    if (!a.json)
        std::printf("\nrandom cuts (%d steps between cuts, 0.9 of the exact limit, enrichment lumping; limit: "
                    "integrator.min_stretch; floor: 0.95 of the uncut exact step, held locally (R1R mass "
                    "scaling), certified (local, then the exact step and keepStep), globally (keepStep) or hybrid "
                    "(the elements under it matched, then certified))\n%-10s %6s "
                    "%9s %6s %6s %9s %9s %14s %15s %13s %12s %11s %9s %13s %14s\n",
                    a.cutSteps, "object", "limit", "floor", "runs", "cuts", "steps", "failures", "inverted runs",
                    "inverted at end", "limited runs", "min dt ratio", "below floor", "topped up", "max mass add",
                    "floor ms/cut");
    std::vector<std::pair<std::string, Model>> objects;
    objects.emplace_back("bar", randomCutBarModel());
    const std::string liver = std::string(CUTSIM_DATA_DIR) + "/tet/sofa_liver.msh";
    if (fs::exists(liver)) objects.emplace_back("liver", randomCutLiverModel(readTetMesh(liver, ReadOptions{})));
    unsigned seed = 21;
    for (const auto& [name, model] : objects) {
        // the same sequences plain and with stretch limiting (fem/forces.hpp limitStretch)
        // and with the step floor held locally and globally (timestep/floor.hpp, keepStep), and
        // certified after the hybrid matched every element under it (timestep/hybrid.hpp)
        struct Variant {
            double limit;
            const char* floor;
        };
        using Floor = RandomCutOptions::Floor;
        for (const Variant& v : {Variant{0.0, "-"}, Variant{0.2, "-"}, Variant{0.2, "local"}, Variant{0.2, "certified"},
                                 Variant{0.2, "global"}, Variant{0.2, "hybrid"}}) {
            const double limit = v.limit;
            const std::string fl = v.floor;
            RandomCutOptions ro{MassLumping::Enrichment, 0.9, limit};
            ro.stepFloor = fl == "-" ? 0.0 : 0.95;
            ro.floor = fl == "global"      ? Floor::Global
                       : fl == "certified" ? Floor::Certified
                       : fl == "hybrid"    ? Floor::HybridCertified
                                           : Floor::Local;
            const auto t0 = WallClock::now();
            const RandomCutStats st = runRandomCuts(model, a.cutRuns, a.cutSteps, seed, ro);
            json row = randomCutStatsJson(st);
            row.update({{"object", name}, {"min_stretch", limit}, {"floor", v.floor}, {"seconds", secondsSince(t0)}});
            j["random_cuts"].push_back(row);
            char matched[48] = "";
            if (ro.floor == Floor::HybridCertified)
                std::snprintf(matched, sizeof matched, "  matched <= %.1f%%", 100 * st.maxMatchedShare);
            if (!a.json)
                std::printf(
                    "%-10s %6.2f %9s %6d %6d %9ld %9d %14d %15d %13d %12.4f %11d %9d %12.3f%% %6.3f/%-7.3f%s%s%s\n",
                    name.c_str(), limit, v.floor, st.runs, st.cuts, st.steps, st.failures, st.invertedRuns,
                    st.invertedAtEnd, st.limitedRuns, st.minDtRatio, st.cutsBelowFloor, st.toppedUp,
                    100 * st.maxAddedMass, st.cuts ? 1e3 * st.floorSeconds / st.cuts : 0.0, 1e3 * st.maxFloorSeconds,
                    matched, st.firstFailure.empty() ? "" : "  first: ", st.firstFailure.c_str());
        }
        ++seed;
    }
}

// Section 4: energy drift of a long undamped run at 0.9 of the limit (symplectic Euler): relative
// to the energy put in, largest deviation and final deviation.
void energyDrift(const SweepModel& sm, bool tiny, bool quiet, json& j) {
    Model mm = sm.model;
    mm.gravity.setZero();
    State s = makeState(mm);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int i = 0; i < mm.nodes(); ++i)
        if (mm.invMass(i) > 0) s.v.col(i) << 1e-3 * u(rng), 1e-3 * u(rng), 1e-3 * u(rng);
    const double dt = 0.9 * exactCriticalDt(mm).dt;
    const long n = tiny ? 2000 : 200000;
    // Symplectic Euler conserves a shadow energy: the measured one oscillates (by O(omega dt),
    // large near the limit) but must not drift. Drift: mean over the last tenth of the run
    // minus mean over the first tenth, sampled every step.
    Stepper st;
    const double e0 = kineticEnergy(mm, s);
    double maxDev = 0, first = 0, last = 0;
    const long tenth = n / 10;
    for (long k = 0; k < n; ++k) {
        st.step(mm, s, StepOptions{Integrator::SymplecticEuler, dt});
        if (k < tenth || k >= n - tenth) {
            const double e = kineticEnergy(mm, s) + elasticEnergy(mm, s);
            (k < tenth ? first : last) += e / tenth;
            maxDev = std::max(maxDev, std::abs(e - e0) / e0);
        }
    }
    const double drift = (last - first) / e0;
    j["energy_drift"] = {{"mesh", sm.name},       {"integrator", "symplectic_euler"},
                         {"fraction", 0.9},       {"steps", n},
                         {"oscillation", maxDev}, {"drift", drift}};
    if (!quiet)
        std::printf("\nenergy, %s, symplectic Euler at 0.9, %ld steps: oscillation max |E-E0|/E0 = %.3e, "
                    "drift (last tenth - first tenth)/E0 = %.3e\n",
                    sm.name.c_str(), n, maxDev, drift);
}

int runStability(const StabilityArgs& a) {
    const json machine = machineJson();
    const std::vector<SweepModel> models = sweepModels(a.tiny);
    const int steps = a.tiny ? std::min(a.steps, 400) : a.steps;
    json j;
    j["steps"] = steps;
    j["energy_factor"] = 1e3;
    sweepSchemes(models, steps, a.json, j);
    sweepAfterCuts(a.tiny, steps, a.json, j);
    randomCutSequences(a, j);
    energyDrift(models[0], a.tiny, a.json, j);
    if (a.json) printResult(j, machine);
    return 0;
}

void stabilityOptions(CLI::App& c, StabilityArgs& a) {
    jsonFlag(c, a.json,
             "{steps, sweeps: [{mesh, integrator, scheme, largest_stable_fraction, runs}], "
             "after_cuts: [{mesh, lumping, dt_ratio, largest_stable_fraction, runs}], "
             "random_cuts: [{object, min_stretch, runs, cuts, steps, failures, inverted_runs, inverted_at_end, "
             "limited_runs, min_dt_ratio}], energy_drift}",
             true);
    c.add_option("--steps", a.steps, "Steps per run")->check(CLI::Range(10, 1000000))->capture_default_str();
    c.add_option("--cut-runs", a.cutRuns, "Random cut sequences per object (bar, liver); 0 skips them")
        ->check(CLI::Range(0, 100000))
        ->capture_default_str();
    c.add_option("--cut-steps", a.cutSteps, "Steps between two cuts of a random sequence")
        ->check(CLI::Range(1, 1000000))
        ->capture_default_str();
    tinyFlag(c, a.tiny, "a single tet and the notched 20x2x2 cantilever, short runs");
}

}  // namespace

void addStabilityBench() {
    addSubcommand("stability",
                  "dt sweeps from 0.5 to 1.2 of the exact limit: largest stable fraction per "
                  "integrator and scheme, also after XFEM cuts per lumping option; random cut sequences; "
                  "energy drift of a long run",
                  stabilityOptions, runStability);
}

}  // namespace cutsim::bench
