// `cutsim bench cutstep`: the stable step through four plane cuts and the time per cut, per cutting
// method (thesis Tables 5.5 and 5.6) on the SOFA liver and a bar. Methods are entries of methods():
// a name and a factory of a run that keeps its own mesh or model and applies one cut at a time.
// No fixed nodes: the step is that of the free object, so a clamp does not hide a cut's modes.
#include "bench/bench.hpp"
#include "bench/machine.hpp"
#include "bench/options.hpp"
#include "app/commands.hpp"
#include "cut/conforming.hpp"
#include "cut/xfem.hpp"
#include "fem/forces.hpp"
#include "cut/baselines.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "timestep/analyzer.hpp"
#include "timestep/cut_response.hpp"
#include "timestep/floor.hpp"
#include "timestep/hybrid.hpp"
#include "util/stopwatch.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdint>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace cutsim::bench {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr double kCriticalShare = 0.85;  // Table 5.2: critical when the R1R step < 0.85 of the uncut minimum
constexpr double kFloor = 0.95;          // step floor and stepping fraction, of the exact step
constexpr double kNearReach = 2.0;       // local improvement: elements this many mean edges from the plane

struct CutStepArgs {
    bool json = false, tiny = false;
    long long problems = 0;  // the budgeted improvement's work, 0: NearPlaneOptions::budgeted's
    int freeNodes = 0;       // and its free nodes, 0: budgeted's
    std::string only;        // one method alone (its name), else all
};

// One object with its four planes and the uncut reference values.
struct BenchObject {
    std::string name;
    TetMesh mesh;  // [m]
    Material material;
    Model model;  // buildModel(mesh), no fixed nodes
    std::vector<CutPlane> planes;
    double dt0 = 0;      // exact step of the uncut model [s]
    double r1rMin0 = 0;  // smallest R1R step of the uncut model [s]
    double mass = 0;     // [kg]
};

BenchObject makeObject(std::string name, TetMesh mesh, std::vector<CutPlane> planes) {
    BenchObject o;
    o.name = std::move(name);
    o.mesh = std::move(mesh);
    o.model = buildModel(o.mesh, o.material);
    o.model.gravity = Eigen::Vector3d(0, 0, -9.81);
    for (CutPlane& p : planes) p.normal.normalize();
    o.planes = std::move(planes);
    const TimestepAnalyzer ta(o.model);
    o.dt0 = ta.exact(o.model).dt;
    o.r1rMin0 = ta.estimates().r1r.minCoeff();
    o.mass = o.model.mass.sum();
    return o;
}

// The liver of the liver_cuts scene (inches to m) with its four planes, copied from
// assets/scenes/liver_cuts.json cutting.cuts (thesis sec. 5.2); applied here to the rest shape.
BenchObject liverObject(const std::string& path) {
    TetMesh mesh = readTetMesh(path, ReadOptions{});
    mesh.X *= 0.0254;
    return makeObject("liver", std::move(mesh),
                      {{{-0.085, 0.06, 0.0}, {1, 0, 0.15}},
                       {{-0.045, 0.06, 0.0}, {1, 0.1, 0}},
                       {{-0.005, 0.06, 0.0}, {1, -0.1, 0.1}},
                       {{0.0, 0.09, 0.0}, {0.1, 1, 0}}});
}

// The bar of randomCutBarModel, 0.1 x 0.02 x 0.02 m: four planes across it, off the node
// lattice (spacing 0.01 m) and tilted, so they cross elements obliquely.
BenchObject barObject() {
    return makeObject("bar", boxMesh(0.1, 0.02, 0.02, 10, 2, 2),
                      {{{0.023, 0.01, 0.01}, {1, 0.15, 0.05}},
                       {{0.047, 0.01, 0.01}, {1, -0.1, 0.2}},
                       {{0.068, 0.01, 0.01}, {1, 0.2, -0.1}},
                       {{0.086, 0.01, 0.01}, {1, 0.05, 0.25}}});
}

// What one cut of one method measured.
struct CutMeasure {
    int elements = 0;
    int critical = 0;           // elements with an R1R step under kCriticalShare of the uncut minimum
    double dt = 0;              // exact step after the cut [s]
    double cutSeconds = 0;      // the cut itself [s]
    double updateSeconds = 0;   // model rebuild or local step-analysis update [s]
    double improveSeconds = 0;  // local mesh improvement [s]
    double floorSeconds = 0;    // step floor [s]
    double addedMass = 0;       // floor's mass over the object's mass, cumulative [-]
};

void measure(const BenchObject& o, const Model& m, const TimestepAnalyzer& ta, CutMeasure& r) {
    r.elements = m.elements();
    r.dt = ta.exact(m).dt;
    const Eigen::VectorXd& r1r = ta.estimates().r1r;
    r.critical = static_cast<int>((r1r.array() < kCriticalShare * o.r1rMin0).count());
}

// A method's state on one object: cut() applies the next plane and returns what it measured.
class MethodRun {
public:
    virtual ~MethodRun() = default;
    virtual CutMeasure cut(const CutPlane& plane) = 0;
    virtual const Model& model() const = 0;
};

struct Method {
    std::string name;
    std::function<std::unique_ptr<MethodRun>(const BenchObject&, const CutStepArgs&)> start;
};

// Conforming subdivision (thesis sec. 5.2): the mesh is cut and the model rebuilt; optionally the
// elements near the plane are improved (sec. 5.1), every other node fixed: within the budget of
// NearPlaneOptions::budgeted, or at the full setting (100 problems per region element, every
// critical element, rounds judged by the exact step).
enum class Improve : std::uint8_t { None, Budgeted, Full };
class SubdivisionRun : public MethodRun {
public:
    SubdivisionRun(const BenchObject& o, Improve improve, const CutStepArgs& a)
        : o_(o), mesh_(o.mesh), improve_(improve) {
        near_ = NearPlaneOptions::budgeted(o.dt0);
        if (a.problems > 0) near_.maxProblems = a.problems;
        if (a.freeNodes > 0) near_.maxFreeNodes = a.freeNodes;
        if (improve == Improve::Full) {
            near_ = NearPlaneOptions{.dtCritical = o.dt0, .reach = kNearReach};
            if (a.tiny) near_.rounds = 2, near_.maxSeconds = 2;
        }
    }
    CutMeasure cut(const CutPlane& plane) override {
        CutMeasure r;
        Stopwatch sw;
        mesh_ = conformingCut(mesh_, plane, ConformingOptions{}).mesh;
        r.cutSeconds = sw.lap();
        if (improve_ != Improve::None) {
            improveNearPlane(mesh_, plane, o_.material, near_);
            r.improveSeconds = sw.lap();
        }
        model_ = buildModel(mesh_, o_.material);
        model_.gravity = o_.model.gravity;
        ta_.compute(model_);
        r.updateSeconds = sw.lap();
        measure(o_, model_, ta_, r);
        return r;
    }
    const Model& model() const override { return model_; }

private:
    const BenchObject& o_;
    TetMesh mesh_;
    Model model_;
    TimestepAnalyzer ta_;
    Improve improve_;
    NearPlaneOptions near_;
};

// XFEM virtual elements (thesis sec. 2.3): the model is cut in place and the step analysis updated
// locally; optionally the step floor (timestep/floor.hpp) holds 0.95 of the uncut exact step, or
// the hybrid (timestep/hybrid.hpp, sec. 5.2.1) matches the elements under 1.1 dt_sim, dt_sim = 0.95
// of the uncut exact step, on load and after each cut (its critical count is the matched elements).
enum class XfemMode : std::uint8_t { Plain, Floor, Hybrid };
class XfemRun : public MethodRun {
public:
    XfemRun(const BenchObject& o, XfemMode mode) : o_(o), m_(o.model), s_(makeState(m_)), ta_(m_), mode_(mode) {
        eng_.prepare(m_);  // once per object, as a scene does: not part of a cut's time
        if (mode_ == XfemMode::Hybrid) matchCriticalCertified(m_, ta_, kFloor * o_.dt0, {}, true);
        CutResponseOptions ro;
        ro.dtFloor = mode_ == XfemMode::Floor ? kFloor * o_.dt0 : 0.0;
        ro.hybrid = mode_ == XfemMode::Hybrid;
        ro.hybridDtSim = kFloor * o_.dt0;
        ro.exact = mode_ != XfemMode::Plain;  // Plain: the step is measured after, not held
        response_ = CutResponse(ro);
    }
    CutMeasure cut(const CutPlane& plane) override {
        CutMeasure r;
        CutSurface cs;
        cs.point = plane.point;
        cs.normal = plane.normal;
        Stopwatch sw;
        const CutResult cr = eng_.cut(m_, s_, cs);
        r.cutSeconds = sw.lap();
        // the product's after-cut response (timestep/cut_response.hpp)
        const CutResponseResult res = response_.apply(m_, ta_, cr.changedElements, cr.changedNodes);
        r.updateSeconds = res.updateSeconds - res.floor.seconds;
        r.floorSeconds = res.floor.seconds + res.exactSeconds;
        r.addedMass = m_.addedMass.size() ? m_.addedMass.sum() / o_.mass : 0.0;
        measure(o_, m_, ta_, r);
        if (mode_ == XfemMode::Hybrid) r.critical = static_cast<int>(m_.matchedList.size());
        return r;
    }
    const Model& model() const override { return m_; }

private:
    const BenchObject& o_;
    Model m_;
    State s_;
    TimestepAnalyzer ta_;
    CutEngine eng_;
    XfemMode mode_;
    CutResponse response_;
};

// The rows of the tables; a further method is one more entry.
std::vector<Method> methods() {
    auto subdivision = [](Improve improve) {
        return [improve](const BenchObject& o, const CutStepArgs& a) {
            return std::make_unique<SubdivisionRun>(o, improve, a);
        };
    };
    auto xfem = [](XfemMode mode) {
        return [mode](const BenchObject& o, const CutStepArgs&) { return std::make_unique<XfemRun>(o, mode); };
    };
    return {
        {"subdivision", subdivision(Improve::None)},
        {"subdivision+improve", subdivision(Improve::Budgeted)},
        {"subdivision+improve-full", subdivision(Improve::Full)},
        {"xfem", xfem(XfemMode::Plain)},
        {"xfem+floor", xfem(XfemMode::Floor)},
        {"xfem+hybrid", xfem(XfemMode::Hybrid)},
    };
}

// Table 5.6's cost: wall seconds per simulated second of symplectic Euler at dt.
struct Cost {
    long steps = 0;
    double wall = 0, simulated = 0;
};
Cost stepCost(const Model& m0, double dt, double simTime) {
    Model m = m0;
    State s = makeState(m);
    Stepper st;
    const StepOptions opt{Integrator::SymplecticEuler, dt};
    Cost c;
    c.steps = std::clamp(static_cast<long>(std::ceil(simTime / dt)), 1L, 200000L);  // a collapsed step is capped
    Stopwatch sw;
    for (long k = 0; k < c.steps; ++k) st.step(m, s, opt);
    c.wall = sw.seconds();
    c.simulated = static_cast<double>(c.steps) * dt;
    return c;
}

int runCutStep(const CutStepArgs& a) {
    const json machine = machineJson();
    // One thread throughout: on meshes of a few hundred elements a parallel region's start costs
    // more than its work, and a second busy core turns it into millisecond stalls.
    const int threadsBefore = threads();
    setThreads(1);
    std::vector<BenchObject> objects;
    json j;
    const std::string liver = std::string(CUTSIM_DATA_DIR) + "/tet/sofa_liver.msh";
    if (!a.tiny) {
        if (fs::exists(liver))
            objects.push_back(liverObject(liver));
        else
            j["note"] = "liver skipped: data mesh tet/sofa_liver.msh not found";
    }
    objects.push_back(barObject());
    const double simTime = a.tiny ? 0.005 : 0.05;
    if (!a.json) {
        if (j.contains("note")) std::printf("%s\n", j["note"].get<std::string>().c_str());
        std::printf("dt: exact step [ms]; ratio: over the uncut exact step; critical: elements with an R1R step "
                    "< %.2f of the uncut minimum (hybrid: the matched elements); times [ms], 1 thread (floor: the "
                    "floor's or the hybrid's update); mass: floor's added mass [%%]; cost: "
                    "wall s per simulated s at %.2f dt after cut 4\n",
                    kCriticalShare, kFloor);
        std::printf("%-6s %-24s %3s %6s %9s %7s %8s %6s %8s %8s %8s %8s %7s %8s\n", "object", "method", "cut", "tets",
                    "dt", "ratio", "critical", "share", "cut", "update", "improve", "floor", "mass", "cost");
    }
    j["problems"] = a.problems;     // subdivision+improve's budget, 0: NearPlaneOptions::budgeted's
    j["free_nodes"] = a.freeNodes;  // and its free nodes, 0: budgeted's
    j["objects"] = json::array();
    for (const BenchObject& o : objects) {
        json jo = {{"name", o.name},
                   {"tets", o.mesh.elements()},
                   {"dt_uncut", o.dt0},
                   {"r1r_min_uncut", o.r1rMin0},
                   {"critical_below", kCriticalShare * o.r1rMin0},
                   {"planes", json::array()},
                   {"methods", json::array()}};
        for (const CutPlane& p : o.planes)
            jo["planes"].push_back({{"point", {p.point.x(), p.point.y(), p.point.z()}},
                                    {"normal", {p.normal.x(), p.normal.y(), p.normal.z()}}});
        if (!a.json)
            std::printf("%-6s %-24s %3d %6d %9.4f %7.4f %8d %6.3f\n", o.name.c_str(), "uncut", 0, o.mesh.elements(),
                        1e3 * o.dt0, 1.0, 0, 0.0);  // none by definition: all are at or above the minimum
        for (const Method& me : methods()) {
            if (!a.only.empty() && me.name != a.only) continue;
            std::unique_ptr<MethodRun> run = me.start(o, a);
            json jm = {{"name", me.name}, {"cuts", json::array()}};
            for (size_t k = 0; k < o.planes.size(); ++k) {
                const CutMeasure r = run->cut(o.planes[k]);
                const double share = static_cast<double>(r.critical) / r.elements;
                jm["cuts"].push_back({{"cut", k + 1},
                                      {"elements", r.elements},
                                      {"dt_exact", jsonNumber(r.dt)},
                                      {"dt_ratio", jsonNumber(r.dt / o.dt0)},
                                      {"critical", r.critical},
                                      {"critical_share", share},
                                      {"cut_seconds", r.cutSeconds},
                                      {"update_seconds", r.updateSeconds},
                                      {"improve_seconds", r.improveSeconds},
                                      {"floor_seconds", r.floorSeconds},
                                      {"added_mass", r.addedMass}});
                std::string cost = "-";
                if (k + 1 == o.planes.size()) {
                    const Cost c = stepCost(run->model(), kFloor * r.dt, simTime);
                    jm["cost"] = {{"dt", kFloor * r.dt},
                                  {"steps", c.steps},
                                  {"simulated_seconds", c.simulated},
                                  {"wall_seconds", c.wall},
                                  {"wall_per_simulated_second", jsonNumber(c.wall / c.simulated)}};
                    char buf[32];
                    std::snprintf(buf, sizeof buf, "%.3f", c.wall / c.simulated);
                    cost = buf;
                }
                if (!a.json)
                    std::printf("%-6s %-24s %3zu %6d %9.4f %7.4f %8d %6.3f %8.3f %8.3f %8.2f %8.3f %7.3f %8s\n",
                                o.name.c_str(), me.name.c_str(), k + 1, r.elements, 1e3 * r.dt, r.dt / o.dt0,
                                r.critical, share, 1e3 * r.cutSeconds, 1e3 * r.updateSeconds, 1e3 * r.improveSeconds,
                                1e3 * r.floorSeconds, 100 * r.addedMass, cost.c_str());
            }
            jo["methods"].push_back(std::move(jm));
        }
        j["objects"].push_back(std::move(jo));
    }
    setThreads(threadsBefore);
    if (a.json) printResult(j, machine);
    return 0;
}

void cutStepOptions(CLI::App& c, CutStepArgs& a) {
    jsonFlag(c, a.json,
             "{problems, free_nodes, objects: [{name, tets, dt_uncut, r1r_min_uncut, critical_below, planes, methods: "
             "[{name, "
             "cuts: [{cut, elements, dt_exact, dt_ratio, critical, critical_share, cut_seconds, "
             "update_seconds, improve_seconds, floor_seconds, added_mass}], cost}]}]}",
             true);
    tinyFlag(c, a.tiny, "the bar only, short cost runs, small full improvement");
    c.add_option("--only", a.only, "One method alone, by its name in the table");
    c.add_option("--problems", a.problems,
                 "subdivision+improve: R1R problems per cut, ranking included (default: NearPlaneOptions::budgeted)");
    c.add_option("--free-nodes", a.freeNodes,
                 "subdivision+improve: nodes of the worst critical elements set free (default: budgeted)");
}

}  // namespace

void addCutStepBench() {
    addSubcommand("cutstep",
                  "Tables 5.5 and 5.6: exact step, critical elements and time per cut "
                  "through four plane cuts by subdivision (with and without local "
                  "improvement) and XFEM (with and without the step floor); liver "
                  "and bar; cost per simulated second after the last cut",
                  cutStepOptions, runCutStep);
}

}  // namespace cutsim::bench
