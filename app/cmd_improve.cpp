// `cutsim improve`: raise a tet mesh's stable step by smoothing and flips (docs/method.md sec. 4,
// thesis sec. 5.1), and write the improved mesh.
#include "commands.hpp"

#include "improve/improve.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "timestep/timestep.hpp"
#include "util/json_text.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>
#include <memory>
#include <unistd.h>

namespace cutsim::app {
namespace {

struct ImproveArgs {
    std::string mesh, out;
    double scale = 1.0;
    ImproveOptions opts;
    bool json = false, quiet = false, fixedBoundary = false;
};

nlohmann::json statsJson(const MeshStepStats& s) {
    return {{"nodes", s.nodes},      {"tets", s.tets},
            {"dt_exact", s.dtExact}, {"dt_certified", s.dtCertified},
            {"dt_r1r", s.dtR1R},     {"min_dihedral_deg", s.minDihedralDeg},
            {"volume", s.volume}};
}

int runImprove(ImproveArgs& a) {
    if (!a.opts.material.valid()) throw InputError("material: need E > 0, -1 < nu < 0.5, rho > 0");
    if (!(a.opts.maxSeconds > 0)) throw InputError("--max-seconds: must be positive");
    ReadOptions ro;
    ro.scale = a.scale;
    TetMesh mesh = readTetMesh(a.mesh, ro);
    a.opts.moveBoundary = !a.fixedBoundary;
    const bool bar = !a.quiet && !a.json && isatty(STDERR_FILENO);
    a.opts.progress = [&](int round, double seconds, double dt) {
        if (!bar) return;
        const int width = 30, done = static_cast<int>(width * std::min(1.0, seconds / a.opts.maxSeconds));
        std::fprintf(stderr, "\r[%-*s] round %3d  %7.3f s  exact dt %.4f ms", width, std::string(done, '#').c_str(),
                     round, seconds, dt * 1e3);
        std::fflush(stderr);
    };
    const ImproveReport r = improveMesh(mesh, a.opts);
    if (bar) std::fprintf(stderr, "\n");
    if (!a.out.empty()) {
        mesh = spatialOrder(mesh);  // improvement leaves a mesher's order: two threads would lose to one
        const bool vtu = a.out.size() > 4 && a.out.compare(a.out.size() - 4, 4, ".vtu") == 0;
        if (vtu)
            writeVtu(a.out, mesh);
        else
            writeMsh22(a.out, mesh);
    }
    if (a.json) {
        nlohmann::json j;
        j["file"] = a.mesh;
        j["before"] = statsJson(r.before);
        j["after"] = statsJson(r.after);
        j["gain"] = r.after.dtExact / r.before.dtExact;
        j["volume_change"] = r.volumeChange;
        j["boundary_distance"] = r.boundaryDistance;
        j["boundary_distance_rel"] = r.boundaryDistance / r.diagonal;
        j["rounds"] = r.rounds;
        j["best_round"] = r.bestRound;
        j["moves"] = r.moves;
        j["flips23"] = r.flips23;
        j["flips32"] = r.flips32;
        j["collapses"] = r.collapses;
        j["evaluations"] = r.evaluations;
        nlohmann::json sec = nlohmann::json::object();
        for (const auto& [k, v] : r.seconds) sec[k] = v;
        j["seconds"] = sec;
        nlohmann::json hist = nlohmann::json::array();
        for (const auto& p : r.history) hist.push_back({p.seconds, p.dtExact});
        j["history"] = hist;
        if (!a.out.empty()) j["written"] = a.out;
        std::cout << jsonText(j);
        return 0;
    }
    std::printf("mesh:      %s\n", a.mesh.c_str());
    std::printf("material:  E = %g Pa, nu = %g, rho = %g kg/m^3\n\n", a.opts.material.E, a.opts.material.nu,
                a.opts.material.rho);
    std::printf("  %-22s %12s %12s %8s\n", "", "before", "after", "ratio");
    auto row = [](const char* name, double b, double f, const char* unit) {
        std::printf("  %-22s %12.4f %12.4f %8.3f  %s\n", name, b, f, f / b, unit);
    };
    row("exact dt", r.before.dtExact * 1e3, r.after.dtExact * 1e3, "ms");
    row("certified dt", r.before.dtCertified * 1e3, r.after.dtCertified * 1e3, "ms");
    row("R1R dt (min)", r.before.dtR1R * 1e3, r.after.dtR1R * 1e3, "ms");
    row("min dihedral", r.before.minDihedralDeg, r.after.minDihedralDeg, "deg");
    std::printf("  %-22s %12d %12d %8.3f\n", "tets", r.before.tets, r.after.tets, double(r.after.tets) / r.before.tets);
    std::printf("  %-22s %12d %12d\n", "nodes", r.before.nodes, r.after.nodes);
    std::printf("\nvolume change:     %+.3f %%\n", 100 * r.volumeChange);
    std::printf("boundary distance: %.3g m (%.3f %% of the diagonal)\n", r.boundaryDistance,
                100 * r.boundaryDistance / r.diagonal);
    std::printf("rounds:            %d (best %d): %d moves, %d 2-3 flips, %d 3-2 flips, %d collapses\n", r.rounds,
                r.bestRound, r.moves, r.flips23, r.flips32, r.collapses);
    std::printf("seconds:          ");
    for (const auto& [k, v] : r.seconds) std::printf(" %s %.3f", k.c_str(), v);
    std::printf("\n");
    if (!a.out.empty()) std::printf("written:           %s\n", a.out.c_str());
    return 0;
}

}  // namespace

void addImproveCommand(CLI::App& app) {
    auto args = std::make_shared<ImproveArgs>();
    CLI::App* cmd = app.add_subcommand(
        "improve", "Mesh improvement for a larger stable step (thesis sec. 5.1): smoothing, flips and collapses that "
                   "lower the largest reduced-one-ring eigenvalue; the exact step before and after");
    cmd->add_option("MESH", args->mesh, "Tet mesh file (.msh, .node/.ele, .mesh, .vtu)")->required();
    cmd->add_option("--scale", args->scale, "Multiply every coordinate by S to get meters")->check(CLI::PositiveNumber);
    cmd->add_option("--out", args->out,
                    "Write the improved mesh (.msh: Gmsh 2.2, .vtu), its elements and nodes in spatial order (as "
                    "`cutsim mesh --spatial-order`)");
    cmd->add_option("--target-dt", args->opts.targetDt, "Stop once the exact step reaches DT [s]");
    cmd->add_option("--work", args->opts.maxEvaluations,
                    "Work budget in element eigenvalue problems (deterministic); default 140 per element, at "
                    "least 1e5");
    cmd->add_option("--max-seconds", args->opts.maxSeconds,
                    "Wall-time limit besides (a run it stops depends on the machine's speed)")
        ->capture_default_str();
    cmd->add_option("--rounds", args->opts.maxRounds, "Rounds at most")->capture_default_str();
    cmd->add_option("--threads", args->opts.threads,
                    "Threads that smooth disjoint parts of the mesh at once (0: one per core); the result "
                    "depends on this count, and on meshes whose critical elements form one cluster a second "
                    "thread saves little")
        ->capture_default_str();
    cmd->add_option("--E", args->opts.material.E, "Young's modulus [Pa]")->capture_default_str();
    cmd->add_option("--nu", args->opts.material.nu, "Poisson's ratio [-]")->capture_default_str();
    cmd->add_option("--rho", args->opts.material.rho, "Density [kg/m^3]")->capture_default_str();
    cmd->add_option("--max-volume-change", args->opts.maxVolumeChange, "Enclosed volume change at most [-]")
        ->capture_default_str();
    cmd->add_option("--max-boundary-distance", args->opts.maxBoundaryDistance,
                    "New boundary from the old surface at most, over the bounding-box diagonal [-]")
        ->capture_default_str();
    cmd->add_flag("--both-ways", args->opts.boundaryBothWays,
                  "The boundary distance bound holds both ways: the old surface also stays near the new "
                  "boundary (no crease or tip cut away)");
    cmd->add_option(
           "--feature-angle", args->opts.featureAngleDeg,
           "Boundary edges whose faces turn more than this are kept as features (creases slide, corners stay) [deg]")
        ->capture_default_str();
    cmd->add_flag("--fixed-boundary", args->fixedBoundary, "Keep every boundary node where it is");
    cmd->add_flag("--json", args->json,
                  "Print one JSON object: before/after {nodes, tets, dt_exact, dt_certified, dt_r1r, "
                  "min_dihedral_deg, volume}, gain, volume_change, boundary_distance, seconds, history");
    cmd->add_flag("--quiet", args->quiet, "No progress bar");
    cmd->callback([args] { runCommand([&] { return runImprove(*args); }); });
}

}  // namespace cutsim::app
