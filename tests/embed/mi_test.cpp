// Mesh intersection (thesis ch. 6): winding numbers, exact and refined interface volumes, the
// embedded model's time step and deformation against conforming meshes.
#include "embed/clip.hpp"
#include "embed/mi.hpp"
#include "embed/winding.hpp"
#include "mesh/embedding.hpp"
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
    std::vector<Eigen::Vector3d> V = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                                      {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
    std::vector<std::array<int, 3>> F = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                         {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                         {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                         {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
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

TEST(Winding, FirstCrossingOfASegment) {
    // The box [0,1]x[0,2]x[0,3]: from (0.5, 1, 1.5) to (3, 1, 1.5) the segment leaves through
    // x = 1 at 0.5 / 2.5 = 0.2 of it; from (-1, 1, 1.5) to (2, 1, 1.5) it enters at x = 0 (1/3)
    // before leaving at x = 1; a segment inside meets nothing.
    const SurfaceMesh b = boxSurface({0, 0, 0}, {1, 2, 3});
    const WindingTree tree = buildWindingTree(b);
    double at = -1;
    ASSERT_TRUE(firstCrossing(tree, {0.5, 1, 1.5}, {3, 1, 1.5}, at));
    EXPECT_NEAR(at, 0.2, 1e-14);
    ASSERT_TRUE(firstCrossing(tree, {-1, 1, 1.5}, {2, 1, 1.5}, at));
    EXPECT_NEAR(at, 1.0 / 3, 1e-14);
    EXPECT_FALSE(firstCrossing(tree, {0.2, 0.5, 0.5}, {0.8, 1.5, 2.5}, at));
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
    o.cells = 5;
    o.refineLevels = 3;
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
    ASSERT_EQ(err.size(), 4u);
    for (size_t l = 1; l < err.size(); ++l) EXPECT_LT(err[l], err[l - 1]) << "level " << l;
    EXPECT_LT(err.back(), 0.01);
}

TEST(Mi, LiverBunnyKnightVolumesExactAndRefined) {
    // Exact clipping keeps the enclosed volume at any resolution; two levels of the thesis's
    // refinement are within 1% already at 8 cells across (measured: 1e-4 .. 3e-3).
    for (const char* f : {"surface/sofa_liver.obj", "surface/igl_bunny.off", "surface/igl_decimated-knight.off"}) {
        SCOPED_TRACE(f);
        const SurfaceMesh s = readSurfaceMesh(test::data(f));
        MiOptions o;
        o.cells = 8;
        o.refineLevels = 2;
        const MiResult r = buildMi(s, Material{}, o);
        const double V = enclosedVolume(s);
        EXPECT_NEAR(r.embeddedVolume() / V, 1.0, 1e-6);
        double vr = 0;
        for (int t = 0; t < r.lattice.elements(); ++t) vr += tetSignedVolume(r.lattice, t) * r.fractionRefined[2](t);
        EXPECT_NEAR(vr / V, 1.0, 0.01);
        // The render surface rides kept elements with weights summing to 1. A vertex at the tip of a
        // thin feature can sit in a tet whose share fell below minFraction (dropped); it then follows
        // the nearest kept tet of its cube or the next, slightly outside it (measured: knight -0.005).
        int outsideHolder = 0;
        for (int v = 0; v < r.surface.vertices(); ++v) {
            ASSERT_GE(r.surface.element[static_cast<size_t>(v)], 0);
            EXPECT_NEAR(r.surface.weights.col(v).sum(), 1.0, 1e-9);
            EXPECT_GT(r.surface.weights.col(v).minCoeff(), -0.05);
            outsideHolder += r.surface.weights.col(v).minCoeff() < -1e-9;
        }
        EXPECT_LE(outsideHolder, r.surface.vertices() / 100);
    }
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

// Broken surfaces (open holes, non-manifold and duplicated faces, self-intersections; see
// data/SOURCES.md): never a crash; the object is the region where the winding number exceeds 1/2,
// with shares from refinement. Documented results: the tree classifies every lattice node as the
// exact winding-number sum does; the dragon (closed but non-manifold) keeps its volume within 1%;
// the open camel head and Suzanne get a finite, positive volume that closes their holes.
TEST(Mi, BrokenSurfacesGiveTheWindingNumberRegion) {
    for (const char* f : {"broken/igl_camelhead.off", "broken/sofa_dragon.obj", "broken/sofa_suzanne.stl"}) {
        SCOPED_TRACE(f);
        const SurfaceMesh s = readSurfaceMesh(test::data(f));
        EXPECT_FALSE(checkSurface(s).closed());
        MiOptions o;
        o.cells = 6;
        MiResult r;
        ASSERT_NO_THROW(r = buildMi(s, Material{}, o));
        EXPECT_FALSE(r.closed);
        EXPECT_GT(r.model.elements(), 0);
        const double v = r.embeddedVolume();
        EXPECT_TRUE(std::isfinite(v));
        EXPECT_GT(v, 0);
        const Eigen::Vector3d lo = s.V.rowwise().minCoeff(), hi = s.V.rowwise().maxCoeff();
        EXPECT_LT(v, (hi - lo).prod());
        // nodes whose exact winding number is clear of 1/2 (near a hole it is not) are classified alike
        int clear = 0, agree = 0;
        for (int n = 0; n < r.lattice.nodes(); ++n) {
            const double w = windingNumberExact(s, r.lattice.X.col(n));
            if (std::abs(w - 0.5) < 0.1) continue;
            ++clear;
            agree += (w > 0.5) == bool(r.nodeInside[n]);
        }
        EXPECT_EQ(agree, clear);
        EXPECT_GT(clear, r.lattice.nodes() * 9 / 10);
        if (std::string(f) == "broken/sofa_dragon.obj") {
            EXPECT_NEAR(v / enclosedVolume(s), 1.0, 0.01);
        }
    }
}

// Linear static sag of a cantilever under gravity: K u = m g on the free DOFs; returns u (3 x n).
Eigen::Matrix3Xd staticSag(const Model& m, const std::vector<int>& fixed, const Eigen::Vector3d& g) {
    const int n = m.nodes();
    std::vector<int> dof(static_cast<size_t>(3 * n), -1);
    std::vector<char> isFixed(static_cast<size_t>(n), 0);
    for (int i : fixed) isFixed[static_cast<size_t>(i)] = 1;
    int nf = 0;
    for (int i = 0; i < n; ++i)
        if (!isFixed[static_cast<size_t>(i)])
            for (int k = 0; k < 3; ++k) dof[static_cast<size_t>(3 * i + k)] = nf++;
    const Eigen::SparseMatrix<double> K = assembleStiffness(m);
    std::vector<Eigen::Triplet<double>> trips;
    for (int c = 0; c < K.outerSize(); ++c)
        for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it)
            if (dof[static_cast<size_t>(it.row())] >= 0 && dof[static_cast<size_t>(it.col())] >= 0)
                trips.emplace_back(dof[static_cast<size_t>(it.row())], dof[static_cast<size_t>(it.col())], it.value());
    Eigen::SparseMatrix<double> Kf(nf, nf);
    Kf.setFromTriplets(trips.begin(), trips.end());
    Eigen::VectorXd f = Eigen::VectorXd::Zero(nf);
    for (int i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k)
            if (dof[static_cast<size_t>(3 * i + k)] >= 0) f(dof[static_cast<size_t>(3 * i + k)]) = m.mass(i) * g[k];
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(Kf);
    const Eigen::VectorXd uf = ldlt.solve(f);
    Eigen::Matrix3Xd u = Eigen::Matrix3Xd::Zero(3, n);
    for (int i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k)
            if (dof[static_cast<size_t>(3 * i + k)] >= 0) u(k, i) = uf(dof[static_cast<size_t>(3 * i + k)]);
    return u;
}

TEST(Mi, CantileverTipMatchesTheConformingBar) {
    // assets/scenes/bar_sag.json: 1 x 0.1 x 0.1 m in 40 x 4 x 4 cubes, E = 1 MPa, nu = 0.3, rho = 1000,
    // clamped at x = 0, gravity; compared through the linear static sag (its damped equilibrium).
    Material mat;
    mat.E = 1e6;
    const Eigen::Vector3d g(0, 0, -9.81);
    const int nx = 40, ny = 4;
    const double h = 1.0 / nx;
    const Model ref = buildModel(boxMesh(1.0, 0.1, 0.1, nx, ny, ny), mat);
    std::vector<int> refFixed, refTip;
    for (int i = 0; i < ref.nodes(); ++i) {
        if (ref.X(0, i) < 1e-9) refFixed.push_back(i);
        if (ref.X(0, i) > 1 - 1e-9) refTip.push_back(i);
    }
    const Eigen::Matrix3Xd uRef = staticSag(ref, refFixed, g);
    double tipRef = 0;
    for (int i : refTip) tipRef += uRef(2, i) / static_cast<double>(refTip.size());

    // MI: the same bar in a lattice of the same cell size, shifted across so the bar's sides cut
    // through cells (interface elements with shares 0.3 / 0.7); the clamp stays on the plane x = 0.
    MiOptions o;
    o.h = h;
    o.latticeCells = Eigen::Vector3i(nx, ny + 1, ny + 1);
    o.latticeOrigin = Eigen::Vector3d(0, -0.3 * h, -0.3 * h);
    const MiResult r = buildMi(boxSurface({0, 0, 0}, {1.0, 0.1, 0.1}), mat, o);
    EXPECT_GT(r.count(ElementClass::Interface), 0);
    EXPECT_NEAR(r.embeddedVolume(), 0.01, 1e-9);
    std::vector<int> fixed;
    for (int i = 0; i < r.model.nodes(); ++i)
        if (r.model.X(0, i) < 1e-9) fixed.push_back(i);
    const Eigen::Matrix3Xd u = staticSag(r.model, fixed, g);
    // tip: the surface's 4 corners at x = 1, through their embedding weights
    Eigen::Matrix3Xd rest, moved;
    embeddedPositions(r.surface, r.model.tets, r.model.X, rest);
    embeddedPositions(r.surface, r.model.tets, r.model.X + u, moved);
    double tip = 0;
    int nTip = 0;
    for (int v = 0; v < r.surface.vertices(); ++v)
        if (rest(0, v) > 1 - 1e-9) {
            tip += moved(2, v) - rest(2, v);
            ++nTip;
        }
    ASSERT_EQ(nTip, 4);
    tip /= nTip;
    EXPECT_LT(tipRef, 0);
    RecordProperty("tip_ratio", std::to_string(tip / tipRef));
    EXPECT_NEAR(tip / tipRef, 1.0, 0.02) << "MI tip " << tip << " m, conforming " << tipRef << " m";
}

TEST(Mi, BarRowsKeepTheLatticeStep) {
    MiBarOptions o;
    o.cellsAcross = 3;  // 3 x 3 x 31 cells: every cut (z = 2.5, 5, 7.5 cm) falls inside a cell
    const auto rows = miBarRows(o);
    ASSERT_EQ(rows.size(), 4u);
    const double V = 10 * std::pow(o.scale, 3);
    for (const auto& row : rows) {
        SCOPED_TRACE(row.kept);
        RecordProperty("dt_ratio_" + std::to_string(row.kept), std::to_string(row.dtExact / row.dtLattice));
        EXPECT_NEAR(row.volume, row.kept * V, 1e-9 * V);
        EXPECT_LE(row.dtCertified, row.dtExact * (1 + 1e-9));
        // Free corners: a node shared by tets of different shares can raise lambda_max a little
        // (measured 2.4e-6 below at 25%); what MI must not do is let small shares shrink the step.
        EXPECT_GE(row.dtExact, row.dtLattice * 0.99);
        // removing DOFs cannot lower the step (eigenvalue interlacing)
        EXPECT_GE(row.dtOutsideFixed, row.dtExact * (1 - 1e-7));
        // the default keeps the lattice's step, with a few parts per million of mass at most
        RecordProperty("added_mass_" + std::to_string(row.kept), std::to_string(row.addedMassFraction));
        EXPECT_GE(row.dtKept, row.dtLattice * (1 - 1e-9));
        EXPECT_LE(row.dtKept, row.dtLattice * (1 + 1e-4));
        EXPECT_LT(row.addedMassFraction, 1e-5);
        if (row.dtExact >= row.dtLattice * (1 - 1e-9)) {
            EXPECT_EQ(row.addedMassFraction, 0.0);
        }
        if (row.kept < 1) {
            EXPECT_GT(row.interfaceElements, 0);
            EXPECT_LT(row.freeNodesOutsideFixed, row.nodes);  // the outside corners are fixed
        }
    }
    EXPECT_EQ(miBarCellsAlong(3), 31);
    EXPECT_EQ(rows[0].nodes, 4 * 4 * 32);
    EXPECT_EQ(rows[0].freeNodesOutsideFixed, 4 * 4 * 32);
    EXPECT_EQ(rows[0].elements, 6 * 3 * 3 * 31);
    EXPECT_NEAR(rows[0].dtExact / rows[0].dtLattice, 1.0, 1e-7);
    // 50% kept: the cut at z = 15.5 cells keeps cells 16..30 whole and half of cell 15 (16 x 3 x 3
    // cubes); the thesis's rule leaves the 16 nodes of plane 15 fixed.
    EXPECT_EQ(rows[2].elements, 6 * 3 * 3 * 16);
    EXPECT_EQ(rows[2].nodes, 4 * 4 * 17);
    EXPECT_EQ(rows[2].freeNodesOutsideFixed, 4 * 4 * 16);
    // The 25% row is the one below the lattice's step without added mass (2.4e-6, measured).
    EXPECT_LT(rows[3].dtExact, rows[3].dtLattice * (1 - 1e-6));
    EXPECT_GT(rows[3].addedMassFraction, 0.0);
}

// MiOptions::keepLatticeStep on the 2 x 2 x 21 bar, 25% kept, where both rules fall below the
// lattice's step (free corners 1.1e-5, fixed 3.3e-6): checked by a dense eigen-solve, and the
// added mass is reported as it is in the model.
TEST(Mi, KeepLatticeStepMeetsTheLatticeStepByDenseSolve) {
    const Material mat;
    const int c = 2, along = miBarCellsAlong(c);
    const double dtLattice =
        2 / std::sqrt(test::denseLambdaMax(buildModel(test::boxMesh(0.01, 0.01, 0.1, c, c, along), mat)));
    for (bool fixOutside : {false, true}) {
        SCOPED_TRACE(fixOutside);
        MiOptions mo;
        mo.latticeCells = Eigen::Vector3i(c, c, along);
        mo.latticeCellSize = Eigen::Vector3d(0.01 / c, 0.01 / c, 0.1 / along);
        mo.fixOutsideNodes = fixOutside;
        const SurfaceMesh bar = boxSurface(Eigen::Vector3d(0, 0, 0.075), Eigen::Vector3d(0.01, 0.01, 0.1));
        const MiResult plain = buildMi(bar, mat, mo);
        EXPECT_LT(2 / std::sqrt(test::denseLambdaMax(plain.model)), dtLattice * (1 - 1e-6));
        EXPECT_EQ(plain.model.addedMass.size(), 0);
        mo.keepLatticeStep = true;
        const MiResult kept = buildMi(bar, mat, mo);
        EXPECT_NEAR(kept.dtLattice, dtLattice, 1e-9 * dtLattice);
        const double dt = 2 / std::sqrt(test::denseLambdaMax(kept.model));
        EXPECT_GE(dt, dtLattice * (1 - 1e-9));
        EXPECT_LE(dt, dtLattice * (1 + 1e-4));
        const KeepStepResult& ks = kept.massScaling;
        EXPECT_TRUE(ks.reached);
        EXPECT_GT(ks.rounds, 1);
        EXPECT_NEAR(ks.dtBefore, 2 / std::sqrt(test::denseLambdaMax(plain.model)), 1e-9 * dt);
        EXPECT_NEAR(ks.addedMass, kept.model.addedMass.sum(), 1e-15);
        EXPECT_NEAR(kept.model.mass.sum() - plain.model.mass.sum(), ks.addedMass, 1e-12 * plain.model.mass.sum());
        EXPECT_GT(ks.massFraction, 0.0);
        EXPECT_LT(ks.massFraction, 1e-5);
        EXPECT_GT(kept.seconds.keepStep, 0.0);
        for (int i = 0; i < kept.model.nodes(); ++i)
            if (kept.model.fixed[i]) {
                EXPECT_EQ(kept.model.addedMass(i), 0.0);
            }
    }
}

// The thesis's rule (outside corners of interface tets fixed, sec. 6.3) against the free-corner
// default on the 1 x 1 x 11 lattice, checked by a dense eigen-solve: there it keeps at least the
// uncut step in every row, the free corners do not (measured -1.2e-6 at 50%, -6.5e-4 at 25%).
// It is no theorem: at 2 x 2 x 21 the 25% row falls 3.3e-6 below with the corners fixed too.
TEST(Mi, BarOutsideFixedRuleAgainstTheUncutStep) {
    const Material mat;
    auto denseDt = [](const Model& m) { return 2 / std::sqrt(test::denseLambdaMax(m)); };
    auto barModel = [&](int c, double kept, bool fixOutside) {
        MiOptions mo;
        mo.latticeCells = Eigen::Vector3i(c, c, miBarCellsAlong(c));
        mo.latticeCellSize = Eigen::Vector3d(0.01 / c, 0.01 / c, 0.1 / miBarCellsAlong(c));
        mo.fixOutsideNodes = fixOutside;
        return buildMi(boxSurface(Eigen::Vector3d(0, 0, 0.1 * (1 - kept)), Eigen::Vector3d(0.01, 0.01, 0.1)), mat, mo)
            .model;
    };
    const double uncut1 = denseDt(buildModel(test::boxMesh(0.01, 0.01, 0.1, 1, 1, 11), mat));
    EXPECT_NEAR(denseDt(barModel(1, 1.0, true)), uncut1, 1e-12 * uncut1);  // the lattice is the uncut bar
    MiBarOptions o;
    o.cellsAcross = 1;
    const auto rows = miBarRows(o, {0.75, 0.5, 0.25});
    ASSERT_EQ(rows.size(), 3u);
    bool freeBelow = false;
    for (const auto& row : rows) {
        SCOPED_TRACE(row.kept);
        const double fixedDt = denseDt(barModel(1, row.kept, true)), freeDt = denseDt(barModel(1, row.kept, false));
        EXPECT_GE(fixedDt, uncut1 * (1 - 1e-9));
        EXPECT_NEAR(row.dtOutsideFixed, fixedDt, 1e-8 * fixedDt);
        EXPECT_NEAR(row.dtExact, freeDt, 1e-8 * freeDt);  // the free-corner variant is reported too
        freeBelow = freeBelow || freeDt < uncut1 * (1 - 1e-9);
    }
    EXPECT_TRUE(freeBelow);
    const double uncut2 = denseDt(buildModel(test::boxMesh(0.01, 0.01, 0.1, 2, 2, 21), mat));
    EXPECT_LT(denseDt(barModel(2, 0.25, true)), uncut2 * (1 - 1e-6));
}

}  // namespace
}  // namespace cutsim
