// cutsim-gmsh-tetra SURFACE OUT SIZE: the tet mesh of a closed surface by Gmsh (Geuzaine and
// Remacle 2009), for `cutsim tetra --mesher gmsh`. The surface's patches between creases are
// reparametrized and remeshed at the target edge (new points lie on the input triangles, creases
// kept as curves), then filled by HXT (Marot et al. 2019) and Gmsh's optimiser. A program of its
// own: Gmsh 4.8 bundles TetGen's symbols, which clash with the TetGen cutsim links.
// Prints one JSON line (the crease angle used, the seconds of each phase); exit 1 when no crease
// angle gives a mesh.
#include "mesh/io.hpp"

#include <gmsh.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

namespace cutsim {
namespace {

// Gmsh 4.8's split of a surface into patches it can parametrize fails on some surfaces at some
// crease angles ("wrong topology of boundary mesh"); the angles are tried in this order, the
// first that gives a mesh is kept. Smaller angles keep more creases.
constexpr double kCreaseAngles[] = {40, 20, 10, 60, 70, 80, 90};

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

struct GmshRun {
    TetMesh mesh;
    double angle = 0, surfaceSeconds = 0, volumeSeconds = 0;
};

// One attempt at crease angle `angle` [deg]; throws (Gmsh's message) when Gmsh fails.
GmshRun meshAt(const SurfaceMesh& s, double size, double angle) {
    gmsh::model::add("tetra");
    const int surf = gmsh::model::addDiscreteEntity(2);
    std::vector<std::size_t> tags(static_cast<size_t>(s.vertices()));
    std::vector<double> xyz;
    for (int i = 0; i < s.vertices(); ++i) {
        tags[static_cast<size_t>(i)] = static_cast<std::size_t>(i) + 1;
        for (int k = 0; k < 3; ++k) xyz.push_back(s.V(k, i));
    }
    gmsh::model::mesh::addNodes(2, surf, tags, xyz);
    std::vector<std::size_t> tri;
    for (int f = 0; f < s.faces(); ++f)
        for (int k = 0; k < 3; ++k) tri.push_back(static_cast<std::size_t>(s.F(k, f)) + 1);
    gmsh::model::mesh::addElementsByType(surf, 2, {}, tri);
    GmshRun run;
    run.angle = angle;
    double t = now();
    // patches between edges turning by more than `angle`, split further until each can be mapped
    // to the plane (forReparametrization); curves not split at corners (curveAngle 180)
    gmsh::model::mesh::classifySurfaces(angle * M_PI / 180, true, true, M_PI);
    gmsh::model::mesh::createGeometry();
    std::vector<std::pair<int, int>> patches;
    gmsh::model::getEntities(patches, 2);
    std::vector<int> loop;
    for (const auto& p : patches) loop.push_back(p.second);
    gmsh::model::geo::addVolume({gmsh::model::geo::addSurfaceLoop(loop)});
    gmsh::model::geo::synchronize();
    gmsh::option::setNumber("Mesh.MeshSizeMin", 0);
    gmsh::option::setNumber("Mesh.MeshSizeMax", size);
    gmsh::option::setNumber("Mesh.MeshSizeFromPoints", 0);
    gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
    gmsh::option::setNumber("Mesh.MeshSizeExtendFromBoundary", 1);
    gmsh::option::setNumber("Mesh.Algorithm", 6);     // Frontal-Delaunay on the patches
    gmsh::option::setNumber("Mesh.Algorithm3D", 10);  // HXT
    gmsh::option::setNumber("Mesh.Optimize", 1);
    gmsh::model::mesh::generate(2);
    run.surfaceSeconds = now() - t;
    t = now();
    gmsh::model::mesh::generate(3);
    run.volumeSeconds = now() - t;

    std::vector<std::size_t> nodeTags, elemTags, elemNodes;
    std::vector<double> coord, param;
    gmsh::model::mesh::getNodes(nodeTags, coord, param, -1, -1, true, false);
    gmsh::model::mesh::getElementsByType(4, elemTags, elemNodes);
    if (elemTags.empty()) throw std::runtime_error("Gmsh made no tetrahedron");
    // the nodes the tets use, numbered in order of first use
    std::map<std::size_t, Eigen::Index> at;
    for (size_t i = 0; i < nodeTags.size(); ++i) at[nodeTags[i]] = static_cast<Eigen::Index>(i);
    std::map<std::size_t, int> index;
    TetMesh& m = run.mesh;
    m.tets.resize(4, static_cast<Eigen::Index>(elemTags.size()));
    std::vector<Eigen::Index> from;
    for (size_t e = 0; e < elemTags.size(); ++e)
        for (int k = 0; k < 4; ++k) {
            const auto [it, fresh] = index.try_emplace(elemNodes[4 * e + k], static_cast<int>(from.size()));
            if (fresh) from.push_back(at.at(elemNodes[4 * e + k]));
            m.tets(k, static_cast<Eigen::Index>(e)) = it->second;
        }
    m.X.resize(3, static_cast<Eigen::Index>(from.size()));
    for (size_t i = 0; i < from.size(); ++i)
        for (int k = 0; k < 3; ++k) m.X(k, static_cast<Eigen::Index>(i)) = coord[3 * static_cast<size_t>(from[i]) + k];
    for (int e = 0; e < m.elements(); ++e)
        if (tetSignedVolume(m, e) < 0) std::swap(m.tets(2, e), m.tets(3, e));
    return run;
}

}  // namespace
}  // namespace cutsim

int main(int argc, char** argv) {
    if (argc != 4) {
        std::fprintf(stderr, "usage: cutsim-gmsh-tetra SURFACE OUT SIZE\n");
        return 2;
    }
    try {
        const cutsim::SurfaceMesh s = cutsim::readSurfaceMesh(argv[1]);
        const double size = std::atof(argv[3]);
        gmsh::initialize();
        gmsh::option::setNumber("General.Terminal", 0);
        // one thread everywhere: HXT's result depends on the thread count, and the mesh must not
        // depend on the machine
        for (const char* o :
             {"General.NumThreads", "Mesh.MaxNumThreads1D", "Mesh.MaxNumThreads2D", "Mesh.MaxNumThreads3D"})
            gmsh::option::setNumber(o, 1);
        std::string errors;
        for (const double angle : cutsim::kCreaseAngles) {
            try {
                const cutsim::GmshRun run = cutsim::meshAt(s, size, angle);
                cutsim::writeMsh22(argv[2], run.mesh);
                std::printf("{\"angle\": %g, \"surface_seconds\": %.6f, \"volume_seconds\": %.6f}\n", run.angle,
                            run.surfaceSeconds, run.volumeSeconds);
                gmsh::finalize();
                return 0;
            } catch (const std::string& e) {  // Gmsh 4.8 throws its last error message
                errors += (errors.empty() ? "" : "; ") + std::to_string(int(angle)) + " deg: " + e;
            } catch (const std::runtime_error& e) {
                errors += (errors.empty() ? "" : "; ") + std::to_string(int(angle)) + " deg: " + e.what();
            }
            gmsh::clear();
        }
        gmsh::finalize();
        std::fprintf(stderr, "error: Gmsh could not mesh the surface at any crease angle (%s)\n", errors.c_str());
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
    }
    return 1;
}
