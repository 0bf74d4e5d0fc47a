// Mesh intersection (thesis ch. 6): winding numbers, exact and refined interface volumes, the
// embedded model's time step and deformation against conforming meshes.
#include "embed/clip.hpp"
#include "embed/mi.hpp"
#include "embed/winding.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "timestep/timestep.hpp"

#include "test_support.hpp"

#include <Eigen/SparseCholesky>
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>
#include <random>

namespace cutsim {
namespace {

// Unit sphere: an icosahedron subdivided `levels` times, vertices pushed to radius r.
SurfaceMesh icosphere(int levels, double r, const Eigen::Vector3d& c) {
    const double t = (1 + std::sqrt(5.0)) / 2;
    std::vector<Eigen::Vector3d> V = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                                      {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    std::vector<std::array<int, 3>> F = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                         {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                                         {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    for (int l = 0; l < levels; ++l) {
        std::map<std::pair<int, int>, int> mid;
        auto m = [&](int a, int b) {
            const auto key = std::minmax(a, b);
            auto it = mid.find(key);
            if (it != mid.end()) return it->second;
            V.push_back(0.5 * (V[a] + V[b]));
            return mid[key] = static_cast<int>(V.size()) - 1;
        };
        std::vector<std::array<int, 3>> G;
        for (const auto& f : F) {
            const int a = m(f[0], f[1]), b = m(f[1], f[2]), d = m(f[2], f[0]);
            G.push_back({f[0], a, d});
            G.push_back({f[1], b, a});
            G.push_back({f[2], d, b});
            G.push_back({a, b, d});
        }
        F = G;
    }
    SurfaceMesh s;
    s.V.resize(3, static_cast<Eigen::Index>(V.size()));
    for (size_t i = 0; i < V.size(); ++i) s.V.col(static_cast<Eigen::Index>(i)) = c + r * V[i].normalized();
    s.F.resize(3, static_cast<Eigen::Index>(F.size()));
    for (size_t i = 0; i < F.size(); ++i) s.F.col(static_cast<Eigen::Index>(i)) << F[i][0], F[i][1], F[i][2];
    s.source = "icosphere";
    return s;
}

double latticeSum(const MiResult& r) {
    double v = 0;
    for (int t = 0; t < r.lattice.elements(); ++t) v += tetSignedVolume(r.lattice, t) * r.fractionExact(t);
    return v;
}

TEST(Winding, BoxSurfaceIsClosedAndOutward) {
    const SurfaceMesh b = boxSurface({0, 0, 0}, {1, 2, 3});
    EXPECT_NEAR(enclosedVolume(b), 6.0, 1e-12);
    EXPECT_TRUE(checkSurface(b).closed());
    EXPECT_NEAR(windingNumberExact(b, {0.5, 1, 1.5}), 1.0, 1e-12);
    EXPECT_NEAR(windingNumberExact(b, {1.5, 1, 1.5}), 0.0, 1e-12);
}

TEST(Winding, TreeMatchesExactSumOnTheBunny) {
    const SurfaceMesh s = readSurfaceMesh(test::data("surface/igl_bunny.off"));
    const WindingTree tree = buildWindingTree(s);
    const Eigen::Vector3d lo = s.V.rowwise().minCoeff(), hi = s.V.rowwise().maxCoeff();
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(0, 1);
    int inside = 0, agree = 0;
    const int n = 300;
    for (int k = 0; k < n; ++k) {
        const Eigen::Vector3d q = lo + (hi - lo).cwiseProduct(Eigen::Vector3d(u(rng), u(rng), u(rng)));
        const double we = windingNumberExact(s, q), wt = windingNumber(tree, q);
        // a closed surface: integer winding numbers away from it
        EXPECT_NEAR(we, std::round(we), 1e-6);
        EXPECT_NEAR(wt, we, 0.1);  // first-order far field at beta = 2
        inside += we > 0.5;
        agree += (we > 0.5) == (wt > 0.5);
    }
    EXPECT_EQ(agree, n);
    EXPECT_GT(inside, 0.1 * n);  // the bunny fills a fair share of its box
}

TEST(Clip, HalfSpaceCutOfTheCornerTet) {
    // Corner tet (V = 1/6) against z < 1/2: the part above is the corner tet scaled by 1/2, so the
    // inside share is 1 - 1/8 for every choice of apex (positively oriented permutations).
    const SurfaceMesh slab = boxSurface({-1, -1, -1}, {2, 2, 0.5});
    std::vector<int> all(12);
    for (int f = 0; f < 12; ++f) all[f] = f;
    const Eigen::Vector3d P[4] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    const int perms[4][4] = {{0, 1, 2, 3}, {1, 0, 3, 2}, {2, 3, 0, 1}, {3, 2, 1, 0}};
    for (const auto& p : perms) {
        const bool p3in = P[p[3]].z() < 0.5;
        EXPECT_NEAR(tetInsideFraction(slab, all, P[p[0]], P[p[1]], P[p[2]], P[p[3]], p3in), 7.0 / 8.0, 1e-12);
    }
    // fully inside and fully outside
    const SurfaceMesh big = boxSurface({-1, -1, -1}, {2, 2, 2});
    EXPECT_NEAR(tetInsideFraction(big, all, P[0], P[1], P[2], P[3], true), 1.0, 1e-12);
    const SurfaceMesh away = boxSurface({3, 3, 3}, {4, 4, 4});
    EXPECT_NEAR(tetInsideFraction(away, all, P[0], P[1], P[2], P[3], false), 0.0, 1e-12);
    // a small box strictly inside the tet, touching no node, edge or face: share = its volume / V
    const SurfaceMesh small = boxSurface({0.1, 0.1, 0.1}, {0.2, 0.25, 0.3});
    EXPECT_NEAR(tetInsideFraction(small, all, P[0], P[1], P[2], P[3], false), 0.1 * 0.15 * 0.2 * 6, 1e-12);
}

TEST(Mi, UnitCubeExactVolumesSumToOne) {
    const SurfaceMesh cube = boxSurface({0.1, 0.2, 0.3}, {1.1, 1.2, 1.3});
    MiOptions o;
    o.h = 0.23;  // cube faces fall between lattice planes
    const MiResult r = buildMi(cube, Material{}, o);
    EXPECT_TRUE(r.closed);
    EXPECT_NEAR(latticeSum(r), 1.0, 1e-9);
    EXPECT_NEAR(r.embeddedVolume(), 1.0, 1e-9);
    EXPECT_GT(r.count(ElementClass::Interface), 0);
    for (int t = 0; t < r.lattice.elements(); ++t) {
        EXPECT_GE(r.fractionExact(t), -1e-9);
        EXPECT_LE(r.fractionExact(t), 1 + 1e-9);
    }
}

TEST(Mi, SphereExactVolumeAndRefinementConverges) {
    const SurfaceMesh s = icosphere(3, 1.0, {0.013, -0.021, 0.034});
    MiOptions o;
    o.cells = 6;
    o.refineLevels = 4;
    const MiResult r = buildMi(s, Material{}, o);
    const double V = enclosedVolume(s);
    EXPECT_NEAR(latticeSum(r), V, 1e-9);
    EXPECT_NEAR(r.embeddedVolume(), V, 1e-5 * V);  // shares within minFraction snap to 0 or 1
    std::vector<double> err;
    for (const auto& fr : r.fractionRefined) {
        double v = 0;
        for (int t = 0; t < r.lattice.elements(); ++t) v += tetSignedVolume(r.lattice, t) * fr(t);
        err.push_back(std::abs(v - V) / V);
    }
    ASSERT_EQ(err.size(), 5u);
    for (size_t l = 1; l < err.size(); ++l) EXPECT_LT(err[l], err[l - 1]) << "level " << l;
    EXPECT_LT(err.back(), 0.01);
}

TEST(Mi, BarOnLatticePlanesIsTheConformingBar) {
    // The surface coincides with lattice planes: MI must give the box mesh itself, with its dt.
    const double h = 0.25;
    MiOptions o;
    o.h = h;
    o.latticeCells = Eigen::Vector3i(6, 4, 4);
    o.latticeOrigin = Eigen::Vector3d(-h, -h, -h);
    const SurfaceMesh bar = boxSurface({0, 0, 0}, {1.0, 0.5, 0.5});
    const MiResult r = buildMi(bar, Material{}, o);
    const TetMesh box = boxMesh(1.0, 0.5, 0.5, 4, 2, 2);
    EXPECT_EQ(r.model.elements(), box.elements());
    EXPECT_EQ(r.model.nodes(), box.nodes());
    EXPECT_EQ(r.count(ElementClass::Interface), 0);
    for (int e = 0; e < r.model.elements(); ++e) EXPECT_EQ(r.model.fraction(e), 1.0);
    const double dtMi = exactCriticalDt(r.model).dt;
    const double dtBox = exactCriticalDt(buildModel(box, Material{})).dt;
    EXPECT_NEAR(dtMi / dtBox, 1.0, 1e-7);
    // lattice nodes on the bar's faces are boundary nodes
    EXPECT_EQ(r.count(NodeClass::Boundary), box.nodes() - 3 * 1 * 1);
}

} // namespace
} // namespace cutsim
