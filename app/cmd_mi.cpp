// `cutsim mi`: embed a surface in a regular background lattice by mesh intersection (thesis ch. 6,
// docs/method.md sec. 5) and report counts, volumes, time steps and the cost of each stage.
#include "commands.hpp"
#include "util/stopwatch.hpp"

#include "embed/mi.hpp"
#include "embed/winding.hpp"
#include "mesh/io.hpp"
#include "timestep/timestep.hpp"
#include "util/json_text.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>

namespace cutsim::app {
namespace {

struct MiArgs {
    std::string surface;
    int cells = 16;
    double h = 0;
    double scale = 1;
    int refine = 0;
    bool fixOutside = false;  // fix the outside corners of interface tets (thesis sec. 6.3)
    bool keepStep = false;    // add mass where needed so the step is at least the lattice's
    Material material;
    bool json = false;
    std::string vtu;
};

// What `cutsim mi` measured: the surface, the embedding, the steps and the seconds they took.
struct MiRun {
    SurfaceMesh s;
    MiResult r;
    SurfaceCheck check;  // of the surface as MI classified it (cleaned)
    ExactResult ex;
    double dtCert = 0, dtBg = 0;                       // certified and lattice steps [s]
    double vSurf = 0, vEmb = 0;                        // [m^3]
    double tRead = 0, tCert = 0, tExact = 0, tBg = 0;  // [s]
};

MiRun measureMi(const MiArgs& a) {
    MiRun run;
    auto t0 = WallClock::now();
    run.s = readSurfaceMesh(a.surface, a.scale);
    run.tRead = secondsSince(t0);
    MiOptions o;
    o.cells = a.cells;
    o.h = a.h;
    o.refineLevels = a.refine;
    o.fixOutsideNodes = a.fixOutside;
    o.keepLatticeStep = a.keepStep;
    run.r = buildMi(run.s, a.material, o);
    SurfaceMesh cleaned = run.s;  // the edges and volume of the surface as MI classified it
    cleanSurface(cleaned, 0);
    run.check = checkSurface(cleaned);

    t0 = WallClock::now();
    const StiffnessRows rows = assembleStiffnessRows(run.r.model);
    run.dtCert = certifiedDt(run.r.model, rows);
    run.tCert = secondsSince(t0);
    t0 = WallClock::now();
    run.ex = exactCriticalDt(run.r.model, rows);
    run.tExact = secondsSince(t0);
    // The lattice's step: already known when the step was kept.
    t0 = WallClock::now();
    run.dtBg = a.keepStep ? run.r.dtLattice : exactCriticalDt(buildModel(run.r.lattice, a.material)).dt;
    run.tBg = a.keepStep ? 0.0 : secondsSince(t0);
    run.vSurf = enclosedVolume(cleaned);
    run.vEmb = run.r.embeddedVolume();
    return run;
}

nlohmann::json miReport(const MiArgs& a, const MiRun& run) {
    const MiResult& r = run.r;
    nlohmann::json j;
    j["file"] = a.surface;
    j["surface"] = {{"vertices", run.s.vertices()},
                    {"triangles", run.s.faces()},
                    {"closed", run.check.closed()},
                    {"open_edges", run.check.openEdges},
                    {"non_manifold_edges", run.check.nonManifoldEdges},
                    {"misoriented_edges", run.check.misorientedEdges},
                    {"welded_vertices", r.cleanup.weldedVertices},
                    {"dropped_duplicate_triangles", r.cleanup.duplicateFaces},
                    {"dropped_degenerate_triangles", r.cleanup.degenerateFaces}};
    j["lattice"] = {{"h", r.h},
                    {"cells", {r.cells.x(), r.cells.y(), r.cells.z()}},
                    {"nodes", r.lattice.nodes()},
                    {"elements", r.lattice.elements()},
                    {"split", "kuhn6"}};
    j["node_classes"] = {{"inside", r.count(NodeClass::Inside)},
                         {"outside", r.count(NodeClass::Outside)},
                         {"boundary", r.count(NodeClass::Boundary)}};
    j["nodes"] = r.model.nodes();
    j["dofs"] = r.model.freeDofs();
    j["fix_outside"] = a.fixOutside;
    j["elements"] = {{"inside", r.count(ElementClass::Inside)},
                     {"interface", r.count(ElementClass::Interface)},
                     {"outside", r.count(ElementClass::Outside)}};
    j["volume_embedded"] = run.vEmb;
    j["volume_surface"] = run.vSurf;
    j["volume_error"] = run.vSurf != 0 ? (run.vEmb - run.vSurf) / run.vSurf : 0.0;
    j["volume_method"] = r.closed ? "exact" : "refined";
    if (!r.fractionRefined.empty()) {
        nlohmann::json lv = nlohmann::json::array();
        for (size_t l = 0; l < r.fractionRefined.size(); ++l) {
            double v = 0;
            for (int t = 0; t < r.lattice.elements(); ++t)
                v += std::abs(tetSignedVolume(r.lattice, t)) * r.fractionRefined[l](t);
            lv.push_back({{"level", l}, {"volume", v}, {"error_vs_exact", r.closed ? (v - run.vEmb) / run.vEmb : 0.0}});
        }
        j["volume_refined"] = lv;
    }
    j["dt_exact"] = run.ex.dt;
    j["dt_certified"] = run.dtCert;
    j["dt_background_exact"] = run.dtBg;
    if (a.keepStep) {
        const KeepStepResult& ks = r.massScaling;
        j["keep_step"] = {{"dt_before", ks.dtBefore}, {"added_mass", ks.addedMass}, {"mass_fraction", ks.massFraction},
                          {"nodes", ks.nodes},        {"rounds", ks.rounds},        {"reached", ks.reached}};
    }
    j["material"] = {{"E", a.material.E}, {"nu", a.material.nu}, {"rho", a.material.rho}};
    const MiTimings& st = r.seconds;
    j["seconds"] = {
        {"read", run.tRead},        {"lattice", st.lattice},     {"hash", st.hash},
        {"nodes", st.nodes},        {"volumes", st.volumes},     {"refine", st.refine},
        {"model", st.model},        {"embed", st.embed},         {"setup", st.total() - st.refine - st.keepStep},
        {"keep_step", st.keepStep}, {"dt_certified", run.tCert}, {"dt_exact", run.tExact},
        {"dt_background", run.tBg}};
    return j;
}

// The model with each element's fraction and whether it is an interface element.
void writeMiVtu(const std::string& path, const MiResult& r) {
    Field frac{"fraction", std::vector<double>(r.model.fraction.data(), r.model.fraction.data() + r.model.elements())};
    Field cls{"interface", std::vector<double>(static_cast<size_t>(r.model.elements()))};
    for (int e = 0; e < r.model.elements(); ++e)
        cls.values[static_cast<size_t>(e)] =
            r.elementClass[static_cast<size_t>(r.latticeElement[static_cast<size_t>(e)])] == ElementClass::Interface;
    writeVtu(path, restMesh(r.model), {frac, cls});
}

void printMi(const MiArgs& a, const MiRun& run, const nlohmann::json& j) {
    const MiResult& r = run.r;
    const SurfaceCheck& check = run.check;
    std::printf("surface:   %s (%d vertices, %d triangles%s)\n", a.surface.c_str(), run.s.vertices(), run.s.faces(),
                check.closed() ? ", closed" : "");
    if (!check.closed())
        std::printf("           not closed: %d open, %d non-manifold, %d misoriented edges; inside shares come from\n"
                    "           %zu refinement levels with winding numbers instead of exact clipping\n",
                    check.openEdges, check.nonManifoldEdges, check.misorientedEdges,
                    r.fractionRefined.empty() ? 0 : r.fractionRefined.size() - 1);
    if (r.cleanup.weldedVertices + r.cleanup.total() > 0)
        std::printf("           cleaned: %d coincident vertices welded, %d duplicate and %d degenerate triangles "
                    "dropped\n",
                    r.cleanup.weldedVertices, r.cleanup.duplicateFaces, r.cleanup.degenerateFaces);
    std::printf("lattice:   h = %.4g m, %d x %d x %d cells, %d nodes, %d tets (Kuhn, 6 per cube)\n", r.h, r.cells.x(),
                r.cells.y(), r.cells.z(), r.lattice.nodes(), r.lattice.elements());
    std::printf("nodes:     %d inside, %d outside, %d boundary (lattice)\n", r.count(NodeClass::Inside),
                r.count(NodeClass::Outside), r.count(NodeClass::Boundary));
    std::printf("elements:  %d inside, %d interface, %d outside\n", r.count(ElementClass::Inside),
                r.count(ElementClass::Interface), r.count(ElementClass::Outside));
    std::printf("model:     %d nodes, %d elements, %d dofs%s\n", r.model.nodes(), r.model.elements(),
                r.model.freeDofs(), a.fixOutside ? " (outside corners of interface tets fixed)" : "");
    std::printf("volume:    embedded %.6g m^3, surface %.6g m^3, error %+.3e\n", run.vEmb, run.vSurf,
                run.vSurf != 0 ? (run.vEmb - run.vSurf) / run.vSurf : 0.0);
    for (const auto& lv : j.value("volume_refined", nlohmann::json::array()))
        if (r.closed)
            std::printf("           refined %d levels: %.6g m^3, error vs exact %+.3e\n", lv["level"].get<int>(),
                        lv["volume"].get<double>(), lv["error_vs_exact"].get<double>());
        else
            std::printf("           refined %d levels: %.6g m^3\n", lv["level"].get<int>(), lv["volume"].get<double>());
    std::printf("dt:        exact %.4f ms, certified %.4f ms; background lattice exact %.4f ms (ratio %.3f)\n",
                run.ex.dt * 1e3, run.dtCert * 1e3, run.dtBg * 1e3, run.ex.dt / run.dtBg);
    if (a.keepStep) {
        const KeepStepResult& ks = r.massScaling;
        std::printf("keep step: exact %.6f ms before; %.3e kg added (%.3e of the mass) on %d nodes, %d eigen-solves\n",
                    ks.dtBefore * 1e3, ks.addedMass, ks.massFraction, ks.nodes, ks.rounds);
    }
    const MiTimings& st = r.seconds;
    std::printf("seconds:   read %.3f, lattice %.3f, hash %.3f, nodes %.3f, volumes %.3f, model %.3f, embed %.3f"
                " (set-up %.3f); refine %.3f; keep step %.3f; dt exact %.3f, certified %.3f, background %.3f\n",
                run.tRead, st.lattice, st.hash, st.nodes, st.volumes, st.model, st.embed,
                st.total() - st.refine - st.keepStep, st.refine, st.keepStep, run.tExact, run.tCert, run.tBg);
    if (!a.vtu.empty()) std::printf("written:   %s\n", a.vtu.c_str());
}

int runMi(const MiArgs& a) {
    try {
        if (!a.material.valid()) throw InputError("material: need E > 0, -1 < nu < 0.5, rho > 0");
        if (a.refine < 0 || a.refine > 8) throw InputError("--refine: must be in [0, 8]");
        const MiRun run = measureMi(a);
        nlohmann::json j = miReport(a, run);
        if (!a.vtu.empty()) {
            writeMiVtu(a.vtu, run.r);
            j["written"] = a.vtu;
        }
        if (a.json)
            std::cout << jsonText(j);
        else
            printMi(a, run, j);
        return 0;
    } catch (const InputError& e) {
        std::cerr << "error: " << e.what() << "\n";
        return 2;
    } catch (const EigenSolveError& e) {
        std::cerr << "error: " << e.what() << "\n";
        return 1;
    }
}

}  // namespace

void addMiCommand(CLI::App& app) {
    auto args = std::make_shared<MiArgs>();
    CLI::App* cmd = app.add_subcommand(
        "mi", "Mesh intersection (thesis ch. 6): embed a closed surface in a regular tet lattice, interface tets "
              "become virtual elements; report counts, enclosed volume, dt of the embedded model and of the lattice");
    cmd->add_option("SURFACE", args->surface, "Surface mesh (.obj, .off, .stl)")->required();
    auto* cells = cmd->add_option("--cells", args->cells, "Lattice cells across the surface's longest side")
                      ->check(CLI::Range(1, 1000))
                      ->capture_default_str();
    auto* h = cmd->add_option("--h", args->h, "Lattice cell edge [m] (after --scale)")->check(CLI::PositiveNumber);
    cells->excludes(h);
    cmd->add_option("--scale", args->scale, "Multiply every coordinate by S to get meters")->check(CLI::PositiveNumber);
    cmd->add_option("--refine", args->refine,
                    "Also compute interface volumes by L levels of refinement (thesis: 5) and report their error "
                    "against the exact volumes")
        ->capture_default_str();
    cmd->add_flag("--fix-outside", args->fixOutside,
                  "Fix the outside corners of interface tets (the thesis's rule, sec. 6.3; pins the object's boundary "
                  "layer, the step can only grow); default: they stay free control points");
    cmd->add_flag("--keep-step", args->keepStep,
                  "Add mass where needed (selective mass scaling) so the embedded model's exact step is at least the "
                  "whole lattice's; reports the mass added (JSON keep_step)");
    cmd->add_option("--E", args->material.E, "Young's modulus [Pa]")->capture_default_str();
    cmd->add_option("--nu", args->material.nu, "Poisson's ratio [-]")->capture_default_str();
    cmd->add_option("--rho", args->material.rho, "Density [kg/m^3]")->capture_default_str();
    cmd->add_flag("--json", args->json,
                  "Print one JSON object: nodes, dofs, elements {inside, interface, outside}, volume_embedded, "
                  "volume_surface [m^3], dt_exact, dt_certified, dt_background_exact [s], seconds {per stage}, ...");
    cmd->add_option("--vtu", args->vtu,
                    "Write the embedded model with per-element fraction and interface flag to OUT.vtu");
    cmd->callback([args] { setExitCode(runMi(*args)); });
}

}  // namespace cutsim::app
