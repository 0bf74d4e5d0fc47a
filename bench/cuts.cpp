// `cutsim bench accuracy` beyond the conforming cantilever, and the post-cut models of
// `bench stability` (BENCHMARKS.md, "Accuracy against cost" and "Stability"):
//   - MI background meshes (thesis ch. 6): the cantilever given only by its surface, embedded in
//     lattices of several resolutions, aligned with the bar and shifted so interface tets exist;
//   - each route through a cut (thesis sec. 2.3.3, 5.2): the cantilever with a notch cut by XFEM
//     (each lumping, the step floor, the hybrid) or by conforming subdivision (alone, with local
//     improvement, with the hybrid), against the same notch meshed conformingly and converged;
//   - the SOFA liver sagging under gravity against a converged backward-Euler equilibrium on a mesh
//     refined twice (each tet into 8).
#include "bench/bench.hpp"
#include "util/stopwatch.hpp"

#include "bench/random_cuts.hpp"
#include "cut/baselines.hpp"
#include "cut/xfem.hpp"
#include "embed/mi.hpp"
#include "mesh/embedding.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "timestep/cut_response.hpp"
#include "timestep/floor.hpp"
#include "timestep/hybrid.hpp"
#include "timestep/modes.hpp"
#include "timestep/timestep.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

namespace cutsim::bench {

using nlohmann::json;

namespace {

void logPoint(const AccuracyContext& ctx, const BenchPoint& p) {
    if (!ctx.quiet)
        std::fprintf(stderr, "  %-28s %-44s error %.3e  cost %.4g s/s\n", p.problem.c_str(), p.config.c_str(), p.error,
                     p.wallPerSimSecond);
}

void clampAndLoad(Model& m, double L) {
    std::vector<int> clamp;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.X(0, i) < 1e-9 * L) clamp.push_back(i);
    fixNodes(m, clamp);
    m.gravity << 0, 0, -9.81;
}

// ---- tip of an embedded bar: the displacement field sampled on the tip face ----

// Mean z displacement over a 5 x 5 grid of cell centres on the face x = L of the bar [0,L]x[0,h]^2,
// each point interpolated in the model element holding it (rest shape). The conforming cantilever
// averages its tip-face nodes instead; on a face that stays flat the two agree.
TipFn sampledTip(const Model& m, double L, double h) {
    struct Sample {
        int e;
        Eigen::Vector4d w;
        Eigen::Vector3d X;
    };
    std::vector<Sample> pts;
    const int n = 5;
    for (int j = 0; j < n; ++j)
        for (int k = 0; k < n; ++k) {
            const Eigen::Vector3d p(L, h * (j + 0.5) / n, h * (k + 0.5) / n);
            int best = -1;
            double bestMin = -INFINITY;
            Eigen::Vector4d bestW;
            for (int e = 0; e < m.elements(); ++e) {
                const Eigen::Vector4d w = barycentric(p, m.X.col(m.tets(0, e)), m.X.col(m.tets(1, e)),
                                                      m.X.col(m.tets(2, e)), m.X.col(m.tets(3, e)));
                if (w.minCoeff() > bestMin) {
                    bestMin = w.minCoeff();
                    best = e;
                    bestW = w;
                }
            }
            pts.push_back({best, bestW, p});
        }
    return [pts](const Model& mm, const Eigen::Matrix3Xd& x) {
        double sum = 0;
        for (const Sample& s : pts) {
            double z = 0;
            for (int a = 0; a < 4; ++a) z += s.w[a] * x(2, mm.tets(a, s.e));
            sum += z - s.X(2);
        }
        return sum / static_cast<double>(pts.size());
    };
}

// ---- MI background meshes ----

// The cantilever as its box surface embedded in a lattice of cell c.h / r: aligned (origin at the
// bar's corner, r cells across) or shifted by `shift` cells in y and z (r + 1 cells across, every
// side face inside a layer of interface tets). Along x the lattice starts at the clamp (x = 0 is a
// lattice plane, its nodes clamped) and ends at the tip (L / h = 10 r cells).
Model miCantilever(const Cantilever& c, int r, double shift, int* interfaceTets) {
    const double h = c.h / r;
    MiOptions o;
    o.h = h;
    const int across = shift > 0 ? r + 1 : r;
    o.latticeCells = Eigen::Vector3i(10 * r, across, across);
    o.latticeOrigin = Eigen::Vector3d(0, -shift * h, -shift * h);
    const MiResult mi = buildMi(boxSurface(Eigen::Vector3d::Zero(), Eigen::Vector3d(c.L, c.h, c.h)), c.material, o);
    Model m = mi.model;
    clampAndLoad(m, c.L);
    if (interfaceTets) *interfaceTets = mi.count(ElementClass::Interface);
    return m;
}

std::vector<BenchPoint> miPoints(const AccuracyContext& ctx) {
    std::vector<BenchPoint> pts;
    auto add = [&](const BenchPoint& p) {
        pts.push_back(p);
        logPoint(ctx, p);
    };
    json info = json::array();
    char name[160];
    // aligned at the coarsest resolution: the lattice is the conforming mesh (a check), then shifted
    struct Cfg {
        int r;
        double shift;
    };
    std::vector<Cfg> cfgs = {{1, 0.0}};
    for (int r = 1; r <= ctx.maxRes; ++r) cfgs.push_back({r, 0.3});
    for (const Cfg& c : cfgs) {
        int iface = 0;
        const Model m = miCantilever(ctx.bar, c.r, c.shift, &iface);
        const double dtExact = exactCriticalDt(m).dt;
        const StepOptions opt{Integrator::SymplecticEuler, 0.9 * dtExact};
        if (c.shift > 0)
            std::snprintf(name, sizeof name, "mi shifted %.1f h=L/%d f=0.9", c.shift, 10 * c.r);
        else
            std::snprintf(name, sizeof name, "mi aligned h=L/%d f=0.9", 10 * c.r);
        TipProbe probe;
        probe.tip = sampledTip(m, ctx.bar.L, ctx.bar.h);
        probe.problem = "";  // the cantilever's problems and references
        add(runStaticPoint(ctx, m, opt, name, probe));
        add(runFrequencyPoint(ctx, m, opt, name, probe));
        info.push_back({{"config", name}, {"tets", m.elements()}, {"interface_tets", iface}, {"dt_exact", dtExact}});
    }
    if (ctx.references) (*ctx.references)["mi_lattices"] = info;
    return pts;
}

// ---- the notched cantilever: lumping after a cut ----

// The notch: the plane x = 0.3125 L through the whole width, from mid-depth (z = h/2) to the top.
// On the 10r x r x r meshes with r even the plane crosses cells (x / cell = 6.25 r / 2) while the
// notch's bottom edge is a lattice line, so XFEM represents the geometry exactly; the conforming
// reference meshes (8n x n x n cubes, n = 2, 4, 8) have both on lattice planes.
constexpr double kNotchX = 0.3125;  // notch plane at kNotchX * L
constexpr double kNotchZ = 0.5;     // notch from kNotchZ * h to the top

CutSurface notchSurface(const Cantilever& c) {
    CutSurface cs;
    cs.point = Eigen::Vector3d(kNotchX * c.L, 0.5 * c.h, kNotchZ * c.h);
    cs.normal = Eigen::Vector3d::UnitX();
    Eigen::Vector3d u, v;
    planeAxes(cs.normal, u, v);
    std::vector<Eigen::Vector2d> poly;
    for (const auto& yz : {Eigen::Vector2d(-c.h, kNotchZ * c.h), Eigen::Vector2d(2 * c.h, kNotchZ * c.h),
                           Eigen::Vector2d(2 * c.h, 2 * c.h), Eigen::Vector2d(-c.h, 2 * c.h)}) {
        const Eigen::Vector3d d = Eigen::Vector3d(kNotchX * c.L, yz[0], yz[1]) - cs.point;
        poly.emplace_back(d.dot(u), d.dot(v));
    }
    cs.regions.push_back(poly);
    return cs;
}

// How the step is kept through the notch (thesis sec. 5.2): nothing beyond the lumping, the step
// floor at 0.95 of the uncut exact step (timestep/floor.hpp), or the hybrid (timestep/hybrid.hpp)
// with dt_sim = 0.95 of it, matched before and after the cut.
enum class NotchRoute : std::uint8_t { Plain, Floor, Hybrid };

// The 10r x r x r cantilever notched by an XFEM cut at rest with the given lumping. *seconds gets
// the time per cut: the cut, the local step-analysis update and the floor or hybrid (the engine's
// bookkeeping of the uncut model is built before, once per object as a scene does).
Model notchedXfem(const Cantilever& c, int r, MassLumping lumping, int* crossed, NotchRoute route = NotchRoute::Plain,
                  double* seconds = nullptr) {
    Model m = cantileverModel(c, r);
    State s = makeState(m);
    CutOptions co;
    co.lumping = lumping;
    CutEngine eng(co);
    eng.prepare(m);
    TimestepAnalyzer ta(m);
    const double dt0 = route == NotchRoute::Plain ? 0.0 : ta.exact(m).dt;
    if (route == NotchRoute::Hybrid) matchCriticalCertified(m, ta, 0.95 * dt0, {}, true);
    CutResponseOptions ro;  // the product's after-cut response (timestep/cut_response.hpp)
    ro.dtFloor = route == NotchRoute::Floor ? 0.95 * dt0 : 0.0;
    ro.hybrid = route == NotchRoute::Hybrid;
    ro.hybridDtSim = 0.95 * dt0;
    ro.exact = route != NotchRoute::Plain;
    CutResponse response(ro);
    const Stopwatch sw;
    const CutResult res = eng.cut(m, s, notchSurface(c));
    if (crossed) *crossed = res.crossed;
    response.apply(m, ta, res.changedElements, res.changedNodes);
    if (seconds) *seconds = sw.seconds();
    return m;
}

// The same notch by the thesis's conforming pipeline (sec. 5.2) on the same bar: the plane split
// through the whole section, opened only above the notch's bottom edge (ConformingOptions::limits),
// snapping at 0.1 (it moves no node here: the plane lies 1/4 or 1/2 a cell off the lattice); then
// nothing, the local improvement (budgeted as in `bench cutstep`, or its full setting, against the
// uncut mesh's step), or the hybrid with dt_sim = 0.95 of the uncut exact step. *seconds: the cut,
// the improvement, the model's rebuild and its step analysis, the hybrid's matching.
enum class SubdivisionRoute : std::uint8_t { Plain, Improve, ImproveFull, Hybrid };
const char* subdivisionRouteName(SubdivisionRoute r) {
    switch (r) {
    case SubdivisionRoute::Plain: return "subdivision";
    case SubdivisionRoute::Improve: return "subdivision+improve";
    case SubdivisionRoute::ImproveFull: return "subdivision+improve-full";
    case SubdivisionRoute::Hybrid: return "subdivision+hybrid";
    }
    return "";
}

Model notchedSubdivision(const Cantilever& c, int r, SubdivisionRoute route, double* seconds, json* parts,
                         ConformingReport* report) {
    const TetMesh uncut = boxMesh(c.L, c.h, c.h, 10 * r, r, r);
    const CutPlane plane{Eigen::Vector3d(kNotchX * c.L, 0, 0), Eigen::Vector3d::UnitX()};
    ConformingOptions co;
    co.limits = {CutPlane{Eigen::Vector3d(0, 0, kNotchZ * c.h), Eigen::Vector3d::UnitZ()}};
    NearPlaneOptions near;
    if (route == SubdivisionRoute::Improve) near = NearPlaneOptions::budgeted(exactDtOf(uncut, c.material));
    if (route == SubdivisionRoute::ImproveFull)
        near = NearPlaneOptions{.dtCritical = exactDtOf(uncut, c.material), .reach = 2.0};
    const double dtSim = route == SubdivisionRoute::Hybrid ? 0.95 * exactCriticalDt(cantileverModel(c, r)).dt : 0.0;
    Stopwatch sw;
    ConformingResult cut = conformingCut(uncut, plane, co);
    const double tCut = sw.lap();
    if (route == SubdivisionRoute::Improve || route == SubdivisionRoute::ImproveFull)
        improveNearPlane(cut.mesh, plane, c.material, near);
    const double tImprove = sw.lap();
    Model m = buildModel(cut.mesh, c.material);
    clampAndLoad(m, c.L);
    TimestepAnalyzer ta(m);
    const double tModel = sw.lap();
    if (route == SubdivisionRoute::Hybrid) matchCriticalCertified(m, ta, dtSim, {}, true);
    const double tHybrid = sw.lap();
    if (seconds) *seconds = sw.seconds();
    if (parts) *parts = {{"cut", tCut}, {"improve", tImprove}, {"model_and_estimates", tModel}, {"hybrid", tHybrid}};
    if (report) *report = cut.report;
    return m;
}

// The fastest of `reps` builds of a notched model, build(&seconds, &parts): its time per cut [s]
// (noise only adds) and that build's parts.
template <class Build>
Model fastestOf(int reps, double* seconds, json* parts, Build build) {
    Model m;
    *seconds = INFINITY;
    for (int k = 0; k < reps; ++k) {
        double t = 0;
        json p;
        Model mk = build(&t, &p);
        if (t < *seconds) *seconds = t, *parts = std::move(p), m = std::move(mk);
    }
    return m;
}

// The notch meshed conformingly: 8n x n x n cubes with the notch plane and its bottom edge on
// lattice planes; nodes on the notch face (above its bottom edge) are duplicated for the tets
// beyond it, so the two faces of the notch come apart.
Model notchedConforming(const Cantilever& c, int n) {
    TetMesh t = boxMesh(c.L, c.h, c.h, 8 * n, n, n);
    const double xc = kNotchX * c.L, zn = kNotchZ * c.h, tol = 1e-9 * c.L;
    std::vector<int> dup(t.nodes(), -1);
    std::vector<Eigen::Vector3d> extra;
    for (int e = 0; e < t.elements(); ++e) {
        double cx = 0;
        for (int a = 0; a < 4; ++a) cx += 0.25 * t.X(0, t.tets(a, e));
        if (cx < xc) continue;
        for (int a = 0; a < 4; ++a) {
            const int i = t.tets(a, e);
            if (std::abs(t.X(0, i) - xc) > tol || t.X(2, i) < zn + tol) continue;
            if (dup[i] < 0) {
                dup[i] = t.nodes() + static_cast<int>(extra.size());
                extra.push_back(t.X.col(i));
            }
            t.tets(a, e) = dup[i];
        }
    }
    const int n0 = t.nodes();
    t.X.conservativeResize(3, n0 + static_cast<Eigen::Index>(extra.size()));
    for (size_t k = 0; k < extra.size(); ++k) t.X.col(n0 + static_cast<Eigen::Index>(k)) = extra[k];
    Model m = buildModel(t, c.material);
    clampAndLoad(m, c.L);
    return m;
}

std::vector<BenchPoint> notchPoints(const AccuracyContext& ctx) {
    std::vector<BenchPoint> pts;
    auto add = [&](const BenchPoint& p) {
        pts.push_back(p);
        logPoint(ctx, p);
    };
    // References: conforming notch meshes, Richardson from the two finest.
    const std::vector<int> levels = ctx.tiny ? std::vector<int>{2, 4} : std::vector<int>{2, 4, 8};
    const BarReferences br = barReferences(levels, [&](int n) { return notchedConforming(ctx.bar, n); });
    TipProbe stat{"cantilever_notch", br.tip, {}};
    TipProbe freq{"cantilever_notch", br.frequency, {}};
    if (ctx.references) {
        (*ctx.references)["cantilever_notch_static"] = {
            {"reference", stat.reference},
            {"levels", levels},
            {"values", br.tips},
            {"notch", {{"x", kNotchX * ctx.bar.L}, {"z_from", kNotchZ * ctx.bar.h}}},
            {"uncut_reference", ctx.tipReference}};
        (*ctx.references)["cantilever_notch_frequency"] = {{"reference", freq.reference},
                                                           {"levels", levels},
                                                           {"values", br.freqs},
                                                           {"uncut_reference", ctx.frequencyReference}};
    }
    char name[160];
    json cuts = json::array(), subdivided = json::array();
    // XFEM on the even meshes, each lumping option, at 0.9 of the cut model's exact limit.
    const int top = ctx.tiny ? 2 : std::max(2, ctx.maxRes);
    const int reps = ctx.tiny ? 1 : 5;
    json parts;
    for (int r = 2; r <= top; r += 2) {
        const double dtUncut = exactCriticalDt(cantileverModel(ctx.bar, r)).dt;
        for (MassLumping l : {MassLumping::RowSum, MassLumping::WeightedDiagonal, MassLumping::Enrichment}) {
            int crossed = 0;
            double sec = 0;
            const Model m = fastestOf(reps, &sec, &parts, [&](double* t, json*) {
                return notchedXfem(ctx.bar, r, l, &crossed, NotchRoute::Plain, t);
            });
            const double dtExact = exactCriticalDt(m).dt;
            const StepOptions opt{Integrator::SymplecticEuler, 0.9 * dtExact};
            std::snprintf(name, sizeof name, "xfem %s %dx%dx%d f=0.9", lumpingName(l), 10 * r, r, r);
            add(runStaticPoint(ctx, m, opt, name, stat));
            add(runFrequencyPoint(ctx, m, opt, name, freq));
            cuts.push_back({{"config", name},
                            {"crossed", crossed},
                            {"tets", m.elements()},
                            {"dt_exact", dtExact},
                            {"dt_ratio", dtExact / dtUncut},
                            {"cut_seconds", sec},
                            {"linear_static_tip", linearStaticTip(m)},
                            {"frequency", firstBendingFrequency(m)}});
        }
        // Enrichment with the step kept by the floor and by the hybrid: the error each costs.
        for (const NotchRoute route : {NotchRoute::Floor, NotchRoute::Hybrid}) {
            const bool hybrid = route == NotchRoute::Hybrid;
            double sec = 0;
            const Model m = fastestOf(reps, &sec, &parts, [&](double* t, json*) {
                return notchedXfem(ctx.bar, r, MassLumping::Enrichment, nullptr, route, t);
            });
            const double dtExact = exactCriticalDt(m).dt;  // the hybrid's: of its FEM part
            const StepOptions opt{Integrator::SymplecticEuler, 0.9 * dtExact};
            std::snprintf(name, sizeof name, "xfem enrichment+%s %dx%dx%d f=0.9", hybrid ? "hybrid" : "floor", 10 * r,
                          r, r);
            add(runStaticPoint(ctx, m, opt, name, stat));
            add(runFrequencyPoint(ctx, m, opt, name, freq));
            json row = {{"config", name},
                        {"tets", m.elements()},
                        {"dt_exact", dtExact},
                        {"dt_ratio", dtExact / dtUncut},
                        {"cut_seconds", sec},
                        {"added_mass", m.addedMass.size() ? m.addedMass.sum() : 0.0},
                        {"matched", m.matchedList.size()}};
            if (!hybrid)  // the linear solves see K only: the hybrid's matched elements are not in it
                row["linear_static_tip"] = linearStaticTip(m), row["frequency"] = firstBendingFrequency(m);
            cuts.push_back(row);
        }
        // The conforming pipeline of sec. 5.2 on the same bar: the step each stage gains, its error.
        for (const SubdivisionRoute route : {SubdivisionRoute::Plain, SubdivisionRoute::Improve,
                                             SubdivisionRoute::ImproveFull, SubdivisionRoute::Hybrid}) {
            const bool hybrid = route == SubdivisionRoute::Hybrid;
            double sec = 0;
            ConformingReport rep;
            const Model m = fastestOf(reps, &sec, &parts, [&](double* t, json* p) {
                return notchedSubdivision(ctx.bar, r, route, t, p, &rep);
            });
            const double dtExact = exactCriticalDt(m).dt;
            const StepOptions opt{Integrator::SymplecticEuler, 0.9 * dtExact};
            std::snprintf(name, sizeof name, "%s %dx%dx%d f=0.9", subdivisionRouteName(route), 10 * r, r, r);
            add(runStaticPoint(ctx, m, opt, name, stat));
            // test size: the static point alone (the slivers' step makes these runs the dearest;
            // the hybrid's softened bar needs more than the test size's 0.5 s to fit a period)
            if (!ctx.tiny) add(runFrequencyPoint(ctx, m, opt, name, freq));
            json row = {{"config", name},
                        {"tets", m.elements()},
                        {"split", rep.splitTets},
                        {"snapped", rep.snappedNodes},
                        {"duplicated", rep.duplicatedNodes},
                        {"dt_exact", dtExact},
                        {"dt_ratio", dtExact / dtUncut},
                        {"cut_seconds", sec},
                        {"cut_seconds_parts", parts},
                        {"matched", m.matchedList.size()}};
            if (!hybrid) row["linear_static_tip"] = linearStaticTip(m), row["frequency"] = firstBendingFrequency(m);
            subdivided.push_back(row);
        }
    }
    // The same notch meshed conformingly, explicit and backward Euler.
    for (int n : ctx.tiny ? std::vector<int>{2} : std::vector<int>{2, 4}) {
        const Model m = notchedConforming(ctx.bar, n);
        const double dtExact = exactCriticalDt(m).dt;
        std::snprintf(name, sizeof name, "conforming notch %dx%dx%d f=0.9", 8 * n, n, n);
        const StepOptions opt{Integrator::SymplecticEuler, 0.9 * dtExact};
        add(runStaticPoint(ctx, m, opt, name, stat));
        add(runFrequencyPoint(ctx, m, opt, name, freq));
        for (double dt : ctx.tiny ? std::vector<double>{0.01} : std::vector<double>{0.03, 0.01}) {
            std::snprintf(name, sizeof name, "backward_euler notch %dx%dx%d dt=%g", 8 * n, n, n, dt);
            const StepOptions be{Integrator::BackwardEuler, dt};
            add(runStaticPoint(ctx, m, be, name, stat));
            add(runFrequencyPoint(ctx, m, be, name, freq));
        }
    }
    if (ctx.references) {
        (*ctx.references)["cantilever_notch_static"]["xfem"] = cuts;
        (*ctx.references)["cantilever_notch_static"]["subdivision"] = subdivided;
    }
    return pts;
}

}  // namespace

// ---- the liver sagging under gravity ----

// The SOFA liver as the demo and liver_cuts scenes set it up (inches to m, E 30 kPa, fixed behind
// z = -0.028 m, gravity -y), refined `levels` times (each tet into 8; coarse nodes keep their
// indices), with mass damping c.
Model liverModel(const TetMesh& inches, int levels, double damping) {
    TetMesh t = inches;
    for (int l = 0; l < levels; ++l) t = refineTets(t);
    Model m = randomCutLiverModel(t, kSceneLiverClampZ);
    m.massDamping = damping;
    return m;
}

// Static equilibrium under gravity: backward Euler at a long step (each step a linearised
// corotational solve, so it is a damped Newton iteration) until the positions stop changing.
Eigen::Matrix3Xd liverEquilibrium(const Model& m0, int* steps) {
    Model m = m0;
    State s = makeState(m);
    Stepper st;
    const StepOptions opt{Integrator::BackwardEuler, 1.0};
    int k = 0;
    for (; k < 400; ++k) {
        const Eigen::Matrix3Xd prev = s.x;
        st.step(m, s, opt);
        if (s.flags.nonFinite) throw EigenSolveError("liver equilibrium: backward Euler gave non-finite values");
        if ((s.x - prev).cwiseAbs().maxCoeff() < 1e-13) break;
    }
    *steps = k + 1;
    return s.x;
}

namespace {

// Relative L2 error of displacements u (3 x n0) at the coarse nodes not fixed in the coarse model.
double displacementError(const std::vector<std::uint8_t>& coarseFixed, const Eigen::Matrix3Xd& u,
                         const Eigen::Matrix3Xd& uRef) {
    double num = 0, den = 0;
    for (int i = 0; i < static_cast<int>(coarseFixed.size()); ++i) {
        if (coarseFixed[static_cast<size_t>(i)]) continue;
        num += (u.col(i) - uRef.col(i)).squaredNorm();
        den += uRef.col(i).squaredNorm();
    }
    return std::sqrt(num / den);
}

// The liver given only by its surface (data/surface/sofa_liver.obj: the same vertex list as the
// tet mesh's nodes, so vertex i is coarse node i), embedded by MI in a lattice of `cells` across,
// set up like liverModel: lattice nodes behind z = -0.028 m fixed, whatever side of the surface.
struct MiLiver {
    Model model;
    EmbeddedSurface surface;  // vertex i rides the element holding coarse node i
};
MiLiver miLiverModel(const SurfaceMesh& inches, int cells, double damping) {
    SurfaceMesh s = inches;
    s.V *= 0.0254;
    MiOptions o;
    o.cells = cells;
    MiResult r = buildMi(s, Material{}, o);
    MiLiver out{std::move(r.model), std::move(r.surface)};
    Model& m = out.model;
    m.gravity = Eigen::Vector3d(0, -9.81, 0);
    for (int i = 0; i < m.nodes(); ++i) m.fixed[static_cast<size_t>(i)] = m.X(2, i) < kSceneLiverClampZ;
    m.massDamping = damping;
    updateMasses(m);
    return out;
}

std::vector<BenchPoint> liverPoints(const AccuracyContext& ctx) {
    std::vector<BenchPoint> pts;
    const std::string path = std::string(CUTSIM_DATA_DIR) + "/tet/sofa_liver.msh";
    if (!std::filesystem::exists(path)) {
        if (!ctx.quiet) std::fprintf(stderr, "  liver_sag: %s not found, skipped\n", path.c_str());
        return pts;
    }
    const TetMesh inches = readTetMesh(path, ReadOptions{});
    const int refLevel = ctx.tiny ? 1 : 2;
    // Damping critical for the coarse liver's lowest mode, c = 2 omega_1, and a run of
    // 12 / omega_1: the transient has decayed to ~1e-4 of the sag.
    const double omega1 = 2 * M_PI * lowestFrequency(liverModel(inches, 0, 0));
    const double c = 2 * omega1, T = (ctx.tiny ? 4 : 12) / omega1;
    const int n0 = inches.nodes();
    std::vector<Eigen::Matrix3Xd> uEq;  // static equilibrium displacement of each level
    json levelInfo = json::array();
    for (int l = 0; l <= refLevel; ++l) {
        const Model m = liverModel(inches, l, c);
        int steps = 0;
        const auto t0 = WallClock::now();
        const Eigen::Matrix3Xd x = liverEquilibrium(m, &steps);
        uEq.push_back(x - m.X);
        levelInfo.push_back({{"level", l},
                             {"tets", m.elements()},
                             {"nodes", m.nodes()},
                             {"equilibrium_steps", steps},
                             {"seconds", secondsSince(t0)}});
    }
    const Eigen::Matrix3Xd& uRef = uEq.back();
    double maxSag = 0;
    for (int i = 0; i < n0; ++i) maxSag = std::max(maxSag, uRef.col(i).norm());
    const std::vector<std::uint8_t> coarseFixed = liverModel(inches, 0, c).fixed;
    for (int l = 0; l < refLevel; ++l)
        levelInfo[static_cast<size_t>(l)]["equilibrium_error"] =
            displacementError(coarseFixed, uEq[static_cast<size_t>(l)].leftCols(n0), uRef);
    if (ctx.references)
        (*ctx.references)["liver_sag"] = {
            {"reference", "backward Euler equilibrium, liver refined " + std::to_string(refLevel) + "x"},
            {"levels", levelInfo},
            {"max_sag_m", maxSag},
            {"omega1", omega1},
            {"damping", c},
            {"sim_time", T},
            {"coarse_nodes", n0}};

    // Displacements at the coarse nodes: the first n0 nodes of a refined mesh, or the embedded
    // vertices of an MI model.
    auto coarseDisplacement = [&](const Model& m, const Eigen::Matrix3Xd& x, const EmbeddedSurface* emb) {
        if (!emb) return Eigen::Matrix3Xd(x.leftCols(n0) - m.X.leftCols(n0));
        Eigen::Matrix3Xd now, rest;
        embeddedPositions(*emb, m.tets, x, now);
        embeddedPositions(*emb, m.tets, m.X, rest);
        return Eigen::Matrix3Xd(now - rest);
    };
    auto run = [&](const Model& m0, const StepOptions& opt, const std::string& config,
                   const EmbeddedSurface* emb = nullptr) {
        Model m = m0;
        State s = makeState(m);
        Stepper st;
        const long n = static_cast<long>(std::ceil(T / opt.dt - 1e-9));
        const auto t0 = WallClock::now();
        for (long k = 0; k < n && s.flags.nonFinite == 0; ++k) st.step(m, s, opt);
        const double wall = secondsSince(t0);
        BenchPoint p;
        p.problem = "liver_sag";
        p.config = config;
        p.dt = opt.dt;
        p.explicitScheme = opt.integrator != Integrator::BackwardEuler;
        p.wallPerSimSecond = wall / s.time;
        p.error = s.flags.nonFinite ? INFINITY : displacementError(coarseFixed, coarseDisplacement(m, s.x, emb), uRef);
        pts.push_back(p);
        logPoint(ctx, p);
    };
    char name[160];
    const int top = ctx.tiny ? 0 : 1;
    for (int l = 0; l <= top; ++l) {
        const Model m = liverModel(inches, l, c);
        const double dtExact = exactCriticalDt(m).dt;
        std::snprintf(name, sizeof name, "explicit liver refined %dx (%d tets) f=0.9", l, m.elements());
        run(m, StepOptions{Integrator::SymplecticEuler, 0.9 * dtExact}, name);
        // Per-element damping past the limit (eq. 3.16, the 5% margin of bench stability): what
        // the larger step costs in accuracy, and whether it stays stable under gravity (the
        // linear-regime sweep reaches 1.5 on the coarse liver).
        const Eigen::VectorXd r1r = estimateElements(m).r1r;
        for (double f : ctx.tiny ? std::vector<double>{1.5} : std::vector<double>{1.25, 1.5}) {
            const Eigen::VectorXd alpha = elementAlpha(0.95 * r1r, f * dtExact);
            StepOptions opt{Integrator::SymplecticEuler, f * dtExact};
            opt.alphaElem = &alpha;
            std::snprintf(name, sizeof name, "explicit alpha_e_0.95 liver refined %dx (%d tets) f=%.3g", l,
                          m.elements(), f);
            run(m, opt, name);
        }
        for (double dt : ctx.tiny ? std::vector<double>{0.03} : std::vector<double>{0.1, 0.03, 0.01}) {
            std::snprintf(name, sizeof name, "backward_euler liver refined %dx (%d tets) dt=%g", l, m.elements(), dt);
            run(m, StepOptions{Integrator::BackwardEuler, dt}, name);
        }
    }
    // MI (thesis ch. 6): the same liver from its surface alone, at several lattice resolutions;
    // its static equilibrium error is reported with the references.
    const std::string surfPath = std::string(CUTSIM_DATA_DIR) + "/surface/sofa_liver.obj";
    if (std::filesystem::exists(surfPath)) {
        const SurfaceMesh surf = readSurfaceMesh(surfPath);
        json miInfo = json::array();
        for (int cells : ctx.tiny ? std::vector<int>{6} : std::vector<int>{8, 12, 16, 24}) {
            const MiLiver mi = miLiverModel(surf, cells, c);
            int steps = 0;
            const Eigen::Matrix3Xd x = liverEquilibrium(mi.model, &steps);
            const double dtExact = exactCriticalDt(mi.model).dt;
            miInfo.push_back({{"cells", cells},
                              {"tets", mi.model.elements()},
                              {"nodes", mi.model.nodes()},
                              {"dt_exact", dtExact},
                              {"equilibrium_error",
                               displacementError(coarseFixed, coarseDisplacement(mi.model, x, &mi.surface), uRef)}});
            std::snprintf(name, sizeof name, "explicit MI liver %d cells (%d tets) f=0.9", cells, mi.model.elements());
            run(mi.model, StepOptions{Integrator::SymplecticEuler, 0.9 * dtExact}, name, &mi.surface);
        }
        if (ctx.references) (*ctx.references)["liver_sag"]["mi"] = miInfo;
    }
    return pts;
}

}  // namespace

std::vector<AfterCutModel> afterCutModels(bool tiny) {
    std::vector<AfterCutModel> out;
    const Cantilever bar;
    const std::vector<MassLumping> lumpings = {MassLumping::RowSum, MassLumping::WeightedDiagonal,
                                               MassLumping::Enrichment};
    {
        const double dt0 = exactCriticalDt(cantileverModel(bar, 2)).dt;
        for (MassLumping l : lumpings) {
            AfterCutModel a;
            a.mesh = "cantilever 20x2x2, notch";
            a.lumping = lumpingName(l);
            a.model = notchedXfem(bar, 2, l, &a.crossed);
            a.dtUncut = dt0;
            out.push_back(std::move(a));
        }
    }
    const std::string path = std::string(CUTSIM_DATA_DIR) + "/tet/sofa_liver.msh";
    if (tiny || !std::filesystem::exists(path)) return out;
    // The liver fixed at its back, cut by the four planes of thesis sec. 5.2 (liver_cuts.json).
    const Model liver = randomCutLiverModel(readTetMesh(path, ReadOptions{}), kSceneLiverClampZ);
    const double dt0 = exactCriticalDt(liver).dt;
    const std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> planes = {{{-0.085, 0.06, 0.0}, {1, 0, 0.15}},
                                                                             {{-0.045, 0.06, 0.0}, {1, 0.1, 0}},
                                                                             {{-0.005, 0.06, 0.0}, {1, -0.1, 0.1}},
                                                                             {{0.0, 0.09, 0.0}, {0.1, 1, 0}}};
    for (MassLumping l : lumpings) {
        AfterCutModel a;
        a.mesh = "liver, 4 planes";
        a.lumping = lumpingName(l);
        a.model = liver;
        a.dtUncut = dt0;
        State s = makeState(a.model);
        CutOptions co;
        co.lumping = l;
        CutEngine eng(co);
        for (const auto& [p, nrm] : planes) {
            CutSurface cs;
            cs.point = p;
            cs.normal = nrm.normalized();
            a.crossed += eng.cut(a.model, s, cs).crossed;
        }
        out.push_back(std::move(a));
    }
    return out;
}

void addCutAccuracyConfigs() {
    addAccuracyConfig("mi", miPoints);
    addAccuracyConfig("notch-lumping", notchPoints);
    addAccuracyConfig("liver", liverPoints);
}

}  // namespace cutsim::bench
