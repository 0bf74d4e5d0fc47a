// `cutsim mesh`: read a tet or surface mesh, print what it holds, optionally convert it.
#include "commands.hpp"

#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "util/json_text.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <utility>

namespace cutsim::app {
namespace {

struct MeshArgs {
    std::string mesh;
    std::string out;
    double scale = 1.0;
    bool reorient = false;
    bool spatialOrder = false;
    bool json = false;
};

std::string lowerExt(const std::string& path) {
    std::string e = std::filesystem::path(path).extension().string();
    for (char& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return e;
}

// Edges used by one triangle only: zero for a closed surface.
int openEdges(const SurfaceMesh& s) {
    std::map<std::pair<int, int>, int> uses;
    for (int f = 0; f < s.faces(); ++f)
        for (int k = 0; k < 3; ++k) {
            const int a = s.F(k, f), b = s.F((k + 1) % 3, f);
            ++uses[{std::min(a, b), std::max(a, b)}];
        }
    int open = 0;
    for (const auto& [edge, n] : uses) open += n == 1;
    return open;
}

int runMesh(const MeshArgs& a) {
    try {
        const std::string ext = lowerExt(a.mesh);
        const bool surface = ext == ".obj" || ext == ".off" || ext == ".stl";
        nlohmann::json j;
        j["file"] = a.mesh;
        j["kind"] = surface ? "surface" : "tet";
        Eigen::Matrix3Xd X;
        if (surface) {
            if (!a.out.empty())
                throw InputError(a.out, 0, "--out converts tet meshes only; " + a.mesh + " is a surface");
            const SurfaceMesh s = readSurfaceMesh(a.mesh, a.scale);
            std::vector<char> used(static_cast<size_t>(s.vertices()), 0);
            for (long i = 0; i < s.F.size(); ++i) used[static_cast<size_t>(s.F.data()[i])] = 1;
            j["nodes"] = s.vertices();
            j["elements"] = s.faces();
            j["skipped_elements"] = 0;
            j["unreferenced_nodes"] = std::count(used.begin(), used.end(), 0);
            j["inverted"] = std::vector<int>{};
            j["boundary_faces"] = s.faces();
            j["open_edges"] = openEdges(s);
            j["volume"] = enclosedVolume(s);
            X = s.V;
        } else {
            ReadOptions opts;
            opts.scale = a.scale;
            opts.reorient = a.reorient;
            ReadReport rep;
            TetMesh m = readTetMesh(a.mesh, opts, &rep);
            if (a.spatialOrder) m = spatialOrder(m);
            j["nodes"] = m.nodes();
            j["elements"] = m.elements();
            j["skipped_elements"] = rep.skippedElements;
            j["unreferenced_nodes"] = rep.unreferencedNodes;
            j["inverted"] = rep.inverted;
            j["boundary_faces"] = boundaryFaces(m).cols();
            j["volume"] = totalVolume(m);
            X = m.X;
            if (!a.out.empty()) {
                const std::string oe = lowerExt(a.out);
                if (oe == ".vtu")
                    writeVtu(a.out, m);
                else if (oe == ".msh")
                    writeMsh22(a.out, m);
                else
                    throw InputError(a.out, 0, "unknown output extension '" + oe + "' (expected .vtu or .msh)");
                j["written"] = a.out;
            }
        }
        const Eigen::Vector3d lo = X.rowwise().minCoeff(), hi = X.rowwise().maxCoeff();
        j["bbox_min"] = {lo.x(), lo.y(), lo.z()};
        j["bbox_max"] = {hi.x(), hi.y(), hi.z()};

        if (a.json) {
            std::cout << jsonText(j);
        } else {
            std::cout << "mesh:                " << a.mesh << " (" << j["kind"].get<std::string>() << ")\n"
                      << "nodes:               " << j["nodes"] << "\n"
                      << "elements:            " << j["elements"] << (surface ? " triangles" : " tets") << "\n"
                      << "skipped elements:    " << j["skipped_elements"] << "\n"
                      << "unreferenced nodes:  " << j["unreferenced_nodes"] << "\n"
                      << "inverted tets:       " << j["inverted"].size()
                      << (j["inverted"].empty() ? "" : (a.reorient ? " (reoriented)" : "")) << "\n"
                      << "boundary faces:      " << j["boundary_faces"] << "\n";
            if (surface) std::cout << "open edges:          " << j["open_edges"] << "\n";
            std::cout << "volume:              " << j["volume"].get<double>() << "\n"
                      << "bounding box:        [" << lo.transpose() << "] .. [" << hi.transpose() << "]\n";
            if (j.contains("written")) std::cout << "written:             " << a.out << "\n";
        }
        return 0;
    } catch (const InputError& e) {
        std::cerr << "error: " << e.what() << "\n";
        return 2;
    }
}

}  // namespace

void addMeshCommand(CLI::App& app) {
    auto args = std::make_shared<MeshArgs>();
    CLI::App* cmd =
        app.add_subcommand("mesh", "Read a tet or surface mesh, check it, print its statistics, convert it");
    cmd->add_option("MESH", args->mesh,
                    "Mesh file: tets from .msh (Gmsh 1, 2.2, 4.1), .node/.ele (TetGen), .mesh (MEDIT), .vtu; "
                    "surfaces from .obj, .off, .stl")
        ->required();
    cmd->add_option("--scale", args->scale, "Multiply every coordinate by S (e.g. 0.01 for cm to m)")
        ->check(CLI::PositiveNumber);
    cmd->add_flag("--reorient", args->reorient, "Fix inverted tets by swapping two nodes instead of rejecting them");
    cmd->add_option("--out", args->out, "Write the tet mesh to FILE.vtu (VTK XML) or FILE.msh (Gmsh 2.2)");
    cmd->add_flag("--spatial-order", args->spatialOrder,
                  "Renumber elements along a Z-order curve and nodes in the order they use them (written with --out): "
                  "two threads then share few nodes, where a mesher's arbitrary order makes them slower than one");
    cmd->add_flag("--json", args->json, "Print the statistics as JSON (lengths in the file's units times --scale)");
    cmd->callback([args] { setExitCode(runMesh(*args)); });
}

}  // namespace cutsim::app
