// cutsim-cgal-remesh IN OUT: CGAL's mesher on a given tet mesh's boundary, then its perturbation
// and exudation (the sliver removers of Mesh_3), at the input's median element size; the CGAL
// baseline of `cutsim bench improve`. CGAL's improvers work on its own triangulations of a domain,
// not on a given mesh of a non-convex object, so the mesh is made again from its surface. In its
// own executable to keep CGAL's templates out of every other build.
#include "mesh/io.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polyhedral_mesh_domain_3.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/exude_mesh_3.h>
#include <CGAL/make_mesh_3.h>
#include <CGAL/perturb_mesh_3.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <vector>

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Surface = CGAL::Surface_mesh<K::Point_3>;
using Domain = CGAL::Polyhedral_mesh_domain_3<Surface, K>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
using Criteria = CGAL::Mesh_criteria_3<Tr>;

cutsim::TetMesh remesh(const cutsim::TetMesh& in) {
    const Eigen::Matrix3Xi F = cutsim::boundaryFaces(in);
    Surface s;
    std::vector<Surface::Vertex_index> v(in.nodes());
    std::vector<char> used(in.nodes(), 0);
    for (int f = 0; f < F.cols(); ++f)
        for (int k = 0; k < 3; ++k) used[F(k, f)] = 1;
    for (int i = 0; i < in.nodes(); ++i)
        if (used[i]) v[i] = s.add_vertex(K::Point_3(in.X(0, i), in.X(1, i), in.X(2, i)));
    for (int f = 0; f < F.cols(); ++f)
        if (s.add_face(v[F(0, f)], v[F(1, f)], v[F(2, f)]) == Surface::null_face())
            throw std::runtime_error("the boundary is not a manifold surface");
    // The edge of the regular tet of the input's median volume sets every size.
    std::vector<double> vol(in.elements());
    for (int e = 0; e < in.elements(); ++e) vol[e] = std::abs(cutsim::tetSignedVolume(in, e));
    std::nth_element(vol.begin(), vol.begin() + vol.size() / 2, vol.end());
    const double a = std::cbrt(6 * std::sqrt(2.0) * vol[vol.size() / 2]);
    namespace p = CGAL::parameters;
    Domain domain(s);
    const Criteria criteria(p::facet_angle = 25, p::facet_size = a, p::facet_distance = 0.1 * a,
                            p::cell_radius_edge_ratio = 2, p::cell_size = a);
    C3t3 c3t3 = CGAL::make_mesh_3<C3t3>(domain, criteria, p::no_perturb(), p::no_exude());
    CGAL::perturb_mesh_3(c3t3, domain, p::time_limit = 30);
    CGAL::exude_mesh_3(c3t3, p::time_limit = 30);
    std::map<Tr::Vertex_handle, int> index;
    std::vector<Eigen::Vector3d> X;
    std::vector<Eigen::Vector4i> T;
    for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
        Eigen::Vector4i t;
        for (int k = 0; k < 4; ++k) {
            const auto h = c->vertex(k);
            auto [it, fresh] = index.try_emplace(h, static_cast<int>(X.size()));
            if (fresh) {
                const auto& q = h->point();
                X.emplace_back(CGAL::to_double(q.x()), CGAL::to_double(q.y()), CGAL::to_double(q.z()));
            }
            t[k] = it->second;
        }
        if (cutsim::tetSignedVolume(X[t[0]], X[t[1]], X[t[2]], X[t[3]]) < 0) std::swap(t[2], t[3]);
        T.push_back(t);
    }
    cutsim::TetMesh out;
    out.X.resize(3, static_cast<Eigen::Index>(X.size()));
    for (size_t i = 0; i < X.size(); ++i) out.X.col(static_cast<Eigen::Index>(i)) = X[i];
    out.tets.resize(4, static_cast<Eigen::Index>(T.size()));
    for (size_t t = 0; t < T.size(); ++t) out.tets.col(static_cast<Eigen::Index>(t)) = T[t];
    return out;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 3) {
        std::fprintf(stderr, "usage: cutsim-cgal-remesh IN OUT\n");
        return 2;
    }
    try {
        cutsim::writeMsh22(argv[2], remesh(cutsim::readTetMesh(argv[1])));
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
    }
    return 1;
}
