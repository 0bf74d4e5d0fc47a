// cutsim-gmsh-optimize IN OUT [METHOD]: Gmsh's tetrahedral optimiser ("" its default, "Netgen")
// on a given tet mesh, boundary nodes held on the boundary; the Gmsh baseline of
// `cutsim bench improve`, in its own process because Gmsh 4.8 and TetGen clash in one.
#include "mesh/io.hpp"

#include <gmsh.h>

#include <cstdio>
#include <map>
#include <string>
#include <vector>

namespace cutsim {
namespace {

// Gmsh's tetrahedral optimisers on a given mesh: the volume as a discrete entity bounded by a
// discrete surface holding the boundary triangles, so boundary nodes stay on it.
TetMesh gmshOptimize(const TetMesh& mesh, const std::string& method) {
    gmsh::initialize();
    gmsh::option::setNumber("General.Terminal", 0);
    gmsh::model::add("improve");
    const Eigen::Matrix3Xi F = boundaryFaces(mesh);
    const int surf = gmsh::model::addDiscreteEntity(2);
    const int vol = gmsh::model::addDiscreteEntity(3, -1, {surf});
    std::vector<char> onBoundary(mesh.nodes(), 0);
    for (int f = 0; f < F.cols(); ++f)
        for (int k = 0; k < 3; ++k) onBoundary[F(k, f)] = 1;
    for (int pass = 0; pass < 2; ++pass) {
        std::vector<std::size_t> tags;
        std::vector<double> xyz;
        for (int i = 0; i < mesh.nodes(); ++i)
            if (onBoundary[i] == (pass == 0)) {
                tags.push_back(static_cast<std::size_t>(i) + 1);
                for (int k = 0; k < 3; ++k) xyz.push_back(mesh.X(k, i));
            }
        gmsh::model::mesh::addNodes(pass == 0 ? 2 : 3, pass == 0 ? surf : vol, tags, xyz);
    }
    std::vector<std::size_t> tri, tet;
    for (int f = 0; f < F.cols(); ++f)
        for (int k = 0; k < 3; ++k) tri.push_back(static_cast<std::size_t>(F(k, f)) + 1);
    for (int e = 0; e < mesh.elements(); ++e)
        for (int k = 0; k < 4; ++k) tet.push_back(static_cast<std::size_t>(mesh.tets(k, e)) + 1);
    gmsh::model::mesh::addElementsByType(surf, 2, {}, tri);
    gmsh::model::mesh::addElementsByType(vol, 4, {}, tet);
    gmsh::model::mesh::optimize(method, true, 10);
    std::vector<std::size_t> nodeTags, elemTags, elemNodes;
    std::vector<double> coord, param;
    gmsh::model::mesh::getNodes(nodeTags, coord, param, -1, -1, false, false);
    gmsh::model::mesh::getElementsByType(4, elemTags, elemNodes);
    gmsh::finalize();
    std::map<std::size_t, int> index;
    TetMesh out;
    out.X.resize(3, static_cast<Eigen::Index>(nodeTags.size()));
    for (size_t i = 0; i < nodeTags.size(); ++i) {
        index[nodeTags[i]] = static_cast<int>(i);
        for (int k = 0; k < 3; ++k) out.X(k, static_cast<Eigen::Index>(i)) = coord[3 * i + k];
    }
    out.tets.resize(4, static_cast<Eigen::Index>(elemTags.size()));
    for (size_t e = 0; e < elemTags.size(); ++e) {
        for (int k = 0; k < 4; ++k) out.tets(k, static_cast<Eigen::Index>(e)) = index.at(elemNodes[4 * e + k]);
        if (tetSignedVolume(out, static_cast<int>(e)) < 0) std::swap(out.tets(2, e), out.tets(3, e));
    }
    out.source = mesh.source;
    return out;
}

}  // namespace
}  // namespace cutsim

int main(int argc, char** argv) {
    if (argc < 3) {
        std::fprintf(stderr, "usage: cutsim-gmsh-optimize IN OUT [METHOD]\n");
        return 2;
    }
    try {
        const cutsim::TetMesh in = cutsim::readTetMesh(argv[1]);
        cutsim::writeMsh22(argv[2], cutsim::gmshOptimize(in, argc > 3 ? argv[3] : ""));
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
    } catch (...) {
        std::fprintf(stderr, "error: Gmsh failed\n");
    }
    return 1;
}
