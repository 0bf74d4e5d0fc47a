// `cutsim tetra`: a closed surface to a simulation-ready tet mesh (sim/tetra.hpp).
#include "commands.hpp"

#include "mesh/io.hpp"
#include "sim/tetra.hpp"
#include "util/json_text.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <string>

namespace cutsim::app {
namespace {

struct TetraArgs {
    std::string surface;
    std::string out;
    double scale = 1;
    bool noImprove = false;
    bool json = false;
    TetraOptions opts;
};

int runTetra(const TetraArgs& a) {
    if (!a.opts.material.valid()) throw InputError("material: need E > 0, -1 < nu < 0.5, rho > 0");
    TetraOptions o = a.opts;
    o.improve = !a.noImprove;
    const TetraResult res = tetraFromSurface(readSurfaceMesh(a.surface, a.scale), o);
    const TetraReport& r = res.report;
    if (!a.out.empty()) {
        const bool vtu = a.out.size() > 4 && a.out.compare(a.out.size() - 4, 4, ".vtu") == 0;
        if (vtu)
            writeVtu(a.out, res.mesh);
        else
            writeMsh22(a.out, res.mesh);
    }
    double total = 0;
    nlohmann::json sec = nlohmann::json::object();
    for (const auto& [k, v] : r.seconds) sec[k] = v, total += v;
    sec["total"] = total;
    const double volumeError = (r.volumeMesh - r.volumeSurface) / r.volumeSurface;
    if (a.json) {
        nlohmann::json j;
        j["surface"] = a.surface;
        j["size"] = o.size;
        j["scale"] = a.scale;
        j["surface_triangles"] = r.surfaceTriangles;
        j["degenerate_triangles"] = r.degenerateTriangles;
        j["mesher"] = r.mesher;
        if (!r.mesherNote.empty()) j["mesher_note"] = r.mesherNote;
        if (r.mesher == "gmsh") {
            j["crease_angle"] = r.creaseAngle;
            j["gmsh_refinements"] = r.gmshRefinements;
            j["gmsh_volume_error"] = r.meshedVolume / r.volumeSurface - 1;
            j["gmsh_boundary_distance_rel"] = r.meshedDistance / r.diagonal;
        }
        j["improver_creases"] = r.improverCreases;
        j["tets_meshed"] = r.tetsMeshed;
        j["elements"] = r.tets;
        j["nodes"] = r.nodes;
        j["dt_before"] = r.dtBefore;
        j["dt_after"] = r.dtAfter;
        j["gain"] = r.dtAfter / r.dtBefore;
        j["regular_edge"] = r.regularEdge;
        j["step_quality"] = r.dtAfter / r.dtScale;
        j["volume_surface"] = r.volumeSurface;
        j["volume_mesh"] = r.volumeMesh;
        j["volume_error"] = volumeError;
        j["boundary_distance"] = r.boundaryDistance;
        j["boundary_distance_rel"] = r.boundaryDistance / r.diagonal;
        j["inverted"] = r.inverted;
        j["min_volume"] = r.minVolume;
        j["seconds"] = sec;
        if (!a.out.empty()) j["written"] = a.out;
        std::cout << jsonText(j);
        return 0;
    }
    std::printf("surface:           %s (%d triangles)\n", a.surface.c_str(), r.surfaceTriangles);
    if (r.mesher == "gmsh")
        std::printf(
            "mesher:            Gmsh (creases over %g deg kept%s; volume %+.3f %%, boundary %.3f %% of the diagonal)\n",
            r.creaseAngle,
            r.gmshRefinements > 0
                ? (", refined " + std::to_string(r.gmshRefinements) + "x where it left the surface").c_str()
                : "",
            100 * (r.meshedVolume / r.volumeSurface - 1), 100 * r.meshedDistance / r.diagonal);
    else
        std::printf("mesher:            TetGen%s%s\n", r.mesherNote.empty() ? "" : ": ", r.mesherNote.c_str());
    std::printf("elements:          %d (%s %d), nodes %d\n", r.tets, r.mesher == "gmsh" ? "Gmsh" : "TetGen",
                r.tetsMeshed, r.nodes);
    std::printf("exact dt:          %.4g ms -> %.4g ms (%.2fx)%s\n", r.dtBefore * 1e3, r.dtAfter * 1e3,
                r.dtAfter / r.dtBefore, r.improverCreases < 180 ? " (improved again, creases kept)" : "");
    std::printf("step quality:      %.3f (exact dt over a / c_p, a = %.3g m: the regular tet of the median volume)\n",
                r.dtAfter / r.dtScale, r.regularEdge);
    std::printf("volume:            %.6g m^3 (surface %.6g, %+.3f %%)\n", r.volumeMesh, r.volumeSurface,
                100 * volumeError);
    std::printf("boundary distance: %.3g m (%.3f %% of the diagonal%s)\n", r.boundaryDistance,
                100 * r.boundaryDistance / r.diagonal, r.mesher == "gmsh" ? ", both ways" : "");
    std::printf("inverted:          %d\n", r.inverted);
    std::printf("seconds:          ");
    for (const auto& [k, v] : r.seconds) std::printf(" %s %.3f", k.c_str(), v);
    std::printf(" (total %.3f)\n", total);
    if (!a.out.empty()) std::printf("written:           %s\n", a.out.c_str());
    return 0;
}

}  // namespace

void addTetraCommand(CLI::App& app) {
    auto args = std::make_shared<TetraArgs>();
    CLI::App* cmd = app.add_subcommand(
        "tetra", "A closed surface to a simulation-ready tet mesh: checked (open, non-manifold, misoriented, "
                 "duplicated or self-intersecting input refused, exit 2), remeshed and filled by Gmsh (or filled by "
                 "TetGen) to a target edge length, improved for the stable step (as `cutsim improve`), put in "
                 "spatial order");
    cmd->add_option("SURFACE", args->surface, "Closed surface (.obj, .off, .stl)")->required();
    cmd->add_option("--size", args->opts.size, "Target edge length H [m, after --scale]")
        ->required()
        ->check(CLI::PositiveNumber);
    cmd->add_option("--scale", args->scale, "Multiply every coordinate by S to get meters")->check(CLI::PositiveNumber);
    cmd->add_option("--out", args->out, "Write the mesh (.msh: Gmsh 2.2, .vtu)");
    cmd->add_option("--mesher", args->opts.mesher,
                    "gmsh: the surface remeshed at the size (creases kept), the volume by HXT (cutsim-gmsh-tetra); "
                    "tetgen: the surface's triangles kept; auto: Gmsh when installed and its mesh keeps the "
                    "volume and boundary within 0.6 %, else TetGen")
        ->transform(CLI::CheckedTransformer(
            std::map<std::string, Mesher>{{"auto", Mesher::Auto}, {"gmsh", Mesher::Gmsh}, {"tetgen", Mesher::TetGen}}))
        ->capture_default_str();
    cmd->add_flag("--no-improve", args->noImprove, "The mesher's mesh in spatial order, not improved");
    cmd->add_option("--threads", args->opts.threads, "Improver threads (the result depends on the count)")
        ->check(CLI::Range(1, 1024))
        ->capture_default_str();
    cmd->add_option("--E", args->opts.material.E, "Young's modulus [Pa], for the exact step")->capture_default_str();
    cmd->add_option("--nu", args->opts.material.nu, "Poisson's ratio [-]")->capture_default_str();
    cmd->add_option("--rho", args->opts.material.rho, "Density [kg/m^3]")->capture_default_str();
    cmd->add_flag("--json", args->json, "Print the report as JSON (times in s, lengths in m)");
    cmd->callback([args] { runCommand([args] { return runTetra(*args); }); });
}

}  // namespace cutsim::app
