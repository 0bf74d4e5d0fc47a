// XFEM virtual elements: exact pieces, conservation, separation, degenerate cuts, the time step.
#include "cut/polyhedron.hpp"
#include "cut/xfem.hpp"
#include "util/union_find.hpp"
#include "fem/forces.hpp"
#include "fem/integrate.hpp"
#include "mesh/embedding.hpp"
#include "mesh/mesh.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <span>
#include <cstdio>
#include <map>
#include <numeric>

namespace cutsim {
namespace {

// Piece label of each node: connected components of elements joined through shared nodes.
std::vector<int> pieceOfNode(const Model& m) {
    UnionFind uf = elementPieces(m.tets, m.nodes());
    std::vector<int> piece(static_cast<size_t>(m.nodes()));
    for (int i = 0; i < m.nodes(); ++i) piece[static_cast<size_t>(i)] = uf.find(i);
    return piece;
}

// Volume (V f) of each piece, ascending (the library's pieceVolumes is largest first).
std::vector<double> piecesAscending(const Model& m) {
    std::vector<double> v = cutsim::pieceVolumes(m);
    std::reverse(v.begin(), v.end());
    return v;
}

Model unitBox(int cells) { return buildModel(test::boxMesh(1, 1, 1, cells, cells, cells), Material{}); }

CutSurface plane(Eigen::Vector3d point, Eigen::Vector3d normal) {
    CutSurface c;
    c.point = point;
    c.normal = normal.normalized();
    return c;
}

// Closed-surface volume of an embedded surface at rest positions (divergence theorem).
double surfaceVolume(const EmbeddedSurface& s, const Model& m, double* cutArea = nullptr) {
    Eigen::Matrix3Xd p;
    embeddedPositions(s, m.tets, m.X, p);
    double v = 0, area = 0;
    for (int f = 0; f < s.faces(); ++f) {
        const Eigen::Vector3d a = p.col(s.triangles(0, f)), b = p.col(s.triangles(1, f)), c = p.col(s.triangles(2, f));
        v += a.dot(b.cross(c)) / 6.0;
        if (s.cutFace(f)) area += 0.5 * (b - a).cross(c - a).norm();
    }
    if (cutArea) *cutArea = area;
    return v;
}

TEST(Polyhedron, ReferenceTetAndClippedCorner) {
    const ConvexPiece t = referenceTet();
    EXPECT_NEAR(volumeFraction(t), 1.0, 1e-15);
    // s = l1 - 1/2: the corner-1 side is a tet scaled by 1/2, volume 1/8.
    Halfspace h;
    h.s << -0.5, 0.5, -0.5, -0.5;
    h.positive = true;
    EXPECT_NEAR(volumeFraction(clip(t, h)), 0.125, 1e-15);
    h.positive = false;
    EXPECT_NEAR(volumeFraction(clip(t, h)), 0.875, 1e-15);
    // int l_a = V/4, int l_a^2 = V/10 over a tet.
    Eigen::Vector4d first, second;
    weightIntegrals(t, first, second);
    EXPECT_NEAR((first.array() - 0.25).abs().maxCoeff(), 0, 1e-15);
    EXPECT_NEAR((second.array() - 0.1).abs().maxCoeff(), 0, 1e-15);
    // Over the corner piece: int l1 / V = 1/8 * (1/2 + 1/4 * 1/2) (centroid value 5/8).
    h.positive = true;
    weightIntegrals(clip(t, h), first, second);
    EXPECT_NEAR(first[1], 0.125 * 0.625, 1e-15);
    EXPECT_NEAR(first.sum(), 0.125, 1e-15);
}

TEST(Polyhedron, FaceAreaAndTies) {
    // s = 1 - 2 m0... keeps the corner-0 quarter of the triangle: area (1/2)^2.
    FaceSide a{{1, -1, -1}, true};
    EXPECT_NEAR(faceAreaFraction({a}), 0.25, 1e-15);
    FaceSide b{{1, -1, -1}, false};
    EXPECT_NEAR(faceAreaFraction({b}), 0.75, 1e-15);
    EXPECT_NEAR(faceAreaFraction({a, b}), 0.0, 1e-15);
    // A plane through the whole face: the face belongs to the positive side only.
    FaceSide on{{0, 0, 0}, true}, off{{0, 0, 0}, false};
    EXPECT_NEAR(faceAreaFraction({on}), 1.0, 1e-15);
    EXPECT_NEAR(faceAreaFraction({off}), 0.0, 1e-15);
}

// A cut within the room reserved for elements (fem/state.hpp reserveElements) appends in place:
// the widest per-element arrays stay where they are, and the same cut without the room gives the
// same model, column for column.
TEST(Xfem, CutAppendsIntoReservedRoom) {
    Model m = unitBox(4), plain = m;
    State s = makeState(m), sPlain = makeState(plain);
    reserveElements(m, s, m.elements() + 200);
    EXPECT_EQ(s.rot.cols(), m.elements() + 200);
    reserveElements(m, s, 1);  // never shrinks
    EXPECT_EQ(m.DmInv.cols(), m.elements() + 200);
    const double* dm = m.DmInv.data();
    const double* rot = s.rot.data();
    const double* fe = s.fe.data();
    CutEngine eng, engPlain;
    const CutResult r = eng.cut(m, s, plane({0.37, 0, 0}, {1, 0, 0}));
    engPlain.cut(plain, sPlain, plane({0.37, 0, 0}, {1, 0, 0}));
    ASSERT_GT(r.split, 0);
    ASSERT_LE(m.elements(), plain.elements() + 200);
    EXPECT_EQ(m.DmInv.data(), dm);
    EXPECT_EQ(s.rot.data(), rot);
    EXPECT_EQ(s.fe.data(), fe);
    ASSERT_EQ(m.elements(), plain.elements());
    EXPECT_EQ(m.tets, plain.tets);
    EXPECT_EQ(m.DmInv.leftCols(m.elements()), plain.DmInv.leftCols(plain.elements()));
    EXPECT_EQ(s.rot.leftCols(m.elements()), sPlain.rot.leftCols(plain.elements()));
}

TEST(Xfem, PlaneCutSplitsBoxExactly) {
    Model m = unitBox(4);
    State s = makeState(m);
    const double mass0 = m.mass.sum();
    CutEngine eng;
    const CutResult r = eng.cut(m, s, plane({0.37, 0, 0}, {1, 0, 0}));
    EXPECT_GT(r.split, 0);
    EXPECT_EQ(r.crossed, r.split);
    EXPECT_EQ(r.dropped, 0);
    EXPECT_NEAR(r.volumeAfter, 1.0, 1e-12);
    EXPECT_NEAR(m.mass.sum(), mass0, 1e-12 * mass0);
    const auto pieces = piecesAscending(m);
    ASSERT_EQ(pieces.size(), 2u);
    EXPECT_NEAR(pieces[0], 0.37, 1e-12);
    EXPECT_NEAR(pieces[1], 0.63, 1e-12);
    // The drawn surface is closed around both pieces: enclosed volume 1, cut faces 2 x 1 m^2.
    double cutArea = 0;
    EXPECT_NEAR(surfaceVolume(eng.surface(m), m, &cutArea), 1.0, 1e-12);
    EXPECT_NEAR(cutArea, 2.0, 1e-12);
    // State arrays follow the model.
    EXPECT_EQ(s.x.cols(), m.nodes());
    EXPECT_GE(s.rot.cols(), m.elements());  // with room for the next cuts' elements
}

// Undirected edges of a triangle mesh used by other than one face each way: 0 for a closed,
// consistently oriented surface whose neighbouring faces share their vertices.
int openEdges(const Eigen::Matrix3Xi& tris) {
    std::map<std::pair<int, int>, int> directed;
    for (int f = 0; f < tris.cols(); ++f)
        for (int k = 0; k < 3; ++k) ++directed[{tris(k, f), tris((k + 1) % 3, f)}];
    int open = 0;
    for (const auto& [e, n] : directed) {
        const auto back = directed.find({e.second, e.first});
        open += n != 1 || back == directed.end() || back->second != 1;
    }
    return open;
}

// The drawn surface of a cut box is one closed surface per piece whose cut faces share their
// edges across elements (smooth shading, no cracks as the pieces deform).
TEST(Xfem, CutSurfaceIsClosedAndItsCutFacesShareEdges) {
    Model m = unitBox(4);
    State s = makeState(m);
    CutEngine eng;
    const CutResult r = eng.cut(m, s, plane({0.37, 0, 0}, {1, 0, 0}));
    ASSERT_EQ(r.dropped, 0);
    const EmbeddedSurface es = eng.surface(m);
    EXPECT_EQ(openEdges(es.triangles), 0);
    // A vertex per distinct place and node set: the cut plane's crossings of the lattice edges
    // are shared by the elements around each edge.
    int cutVertices = 0;
    std::vector<bool> onCut(static_cast<size_t>(es.vertices()));
    for (int f = 0; f < es.faces(); ++f)
        if (es.cutFace(f))
            for (int k = 0; k < 3; ++k) onCut[static_cast<size_t>(es.triangles(k, f))] = true;
    for (bool b : onCut) cutVertices += b;
    EXPECT_LT(cutVertices, es.faces() / 2);
}

// A side below minFraction is dropped, but its faces are drawn on its side: the cut faces still
// cover the whole cross-section on both sides, and the surface is still closed around the box.
TEST(Xfem, DroppedSliversLeaveNoHoleInTheCutFaces) {
    Model m = unitBox(4);
    State s = makeState(m);
    CutEngine eng;
    const CutResult r = eng.cut(m, s, plane({0.26, 0, 0}, {1, 0, 0}));  // 0.01 past a node layer
    ASSERT_GT(r.dropped, 0);
    double cutArea = 0;
    const EmbeddedSurface es = eng.surface(m);
    EXPECT_NEAR(surfaceVolume(es, m, &cutArea), 1.0, 1e-9);
    EXPECT_NEAR(cutArea, 2.0, 1e-9);
    EXPECT_EQ(openEdges(es.triangles), 0);
}

// Mass added to keep a step (model.addedMass) stays on its node through a cut; the copies a cut
// makes start without, so the total mass is unchanged.
TEST(Xfem, AddedMassStaysOnItsNodeThroughACut) {
    Model m = unitBox(4);
    const int n0 = m.nodes();
    m.addedMass = Eigen::VectorXd::LinSpaced(n0, 1.0, 2.0);
    updateMasses(m);
    const double mass0 = m.mass.sum();
    const Eigen::VectorXd added0 = m.addedMass;
    State s = makeState(m);
    CutEngine eng;
    const CutResult r = eng.cut(m, s, plane({0.37, 0, 0}, {1, 0, 0}));
    ASSERT_GT(m.nodes(), n0);
    ASSERT_EQ(m.addedMass.size(), m.nodes());
    EXPECT_EQ(m.addedMass.head(n0), added0);
    EXPECT_EQ(m.addedMass.tail(m.nodes() - n0).cwiseAbs().maxCoeff(), 0.0);
    EXPECT_NEAR(m.mass.sum(), mass0, 1e-12 * mass0);
    EXPECT_NEAR(r.volumeAfter, 1.0, 1e-12);
}

TEST(Xfem, CutsThroughNodesAndFacesSeparateWithoutSlivers) {
    // x = 0.5 passes through a layer of nodes; x = y holds faces of the Kuhn tets.
    for (const CutSurface& c : {plane({0.5, 0, 0}, {1, 0, 0}), plane({0, 0, 0}, {1, -1, 0})}) {
        Model m = unitBox(4);
        State s = makeState(m);
        CutEngine eng;
        const CutResult r = eng.cut(m, s, c);
        EXPECT_TRUE(r.changed());
        EXPECT_EQ(r.split, 0);  // every element lies on one side; only nodes are duplicated
        const auto pieces = piecesAscending(m);
        ASSERT_EQ(pieces.size(), 2u);
        EXPECT_NEAR(pieces[0], 0.5, 1e-12);
        EXPECT_NEAR(pieces[1], 0.5, 1e-12);
        EXPECT_GT(m.fraction.minCoeff(), 0.999999);
        EXPECT_NEAR(surfaceVolume(eng.surface(m), m), 1.0, 1e-12);
    }
}

TEST(Xfem, CrossingCutsMakeFourPieces) {
    Model m = unitBox(3);
    State s = makeState(m);
    CutOptions co;
    co.minFraction = 0;  // exact geometry: the second plane leaves pieces below the default 5%
    CutEngine eng(co);
    eng.cut(m, s, plane({0.37, 0, 0}, {1, 0, 0}));
    eng.cut(m, s, plane({0, 0.61, 0}, {0, 1, 0}));
    const auto pieces = piecesAscending(m);
    ASSERT_EQ(pieces.size(), 4u);
    EXPECT_NEAR(pieces[0], 0.37 * 0.39, 1e-12);
    EXPECT_NEAR(pieces[1], 0.37 * 0.61, 1e-12);
    EXPECT_NEAR(pieces[2], 0.63 * 0.39, 1e-12);
    EXPECT_NEAR(pieces[3], 0.63 * 0.61, 1e-12);
    EXPECT_NEAR(surfaceVolume(eng.surface(m), m), 1.0, 1e-12);
}

TEST(Xfem, MissingPlaneChangesNothing) {
    Model m = unitBox(2);
    State s = makeState(m);
    const int n = m.nodes(), e = m.elements();
    CutEngine eng;
    const CutResult r = eng.cut(m, s, plane({2, 0, 0}, {1, 0, 0}));
    EXPECT_FALSE(r.changed());
    EXPECT_EQ(m.nodes(), n);
    EXPECT_EQ(m.elements(), e);
}

TEST(Xfem, BoundedCutLeavesOnePiece) {
    // Plane x = 0.4 restricted to y < 0.5: the body is cut half-way and stays one piece.
    Model m = unitBox(4);
    State s = makeState(m);
    CutSurface c = plane({0.4, 0, 0}, {1, 0, 0});
    Eigen::Vector3d u, v;
    planeAxes(c.normal, u, v);
    std::vector<Eigen::Vector2d> poly;
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(0.4, -1, -1), Eigen::Vector3d(0.4, 0.5, -1),
                                     Eigen::Vector3d(0.4, 0.5, 2), Eigen::Vector3d(0.4, -1, 2)})
        poly.emplace_back((p - c.point).dot(u), (p - c.point).dot(v));
    c.regions.push_back(poly);
    CutEngine eng;
    const CutResult r = eng.cut(m, s, c);
    EXPECT_GT(r.split, 0);
    EXPECT_GT(r.pending, 0);
    EXPECT_EQ(piecesAscending(m).size(), 1u);
    EXPECT_NEAR(r.volumeAfter, 1.0, 1e-12);
    EXPECT_NEAR(surfaceVolume(eng.surface(m), m), 1.0, 1e-12);
}

TEST(Xfem, BladeSweepSeparatesOnlyWhenThrough) {
    Model m = unitBox(4);
    State s = makeState(m);
    CutOptions co;
    co.minFraction = 0;      // exact geometry: x = 0.43 leaves sides below the default 5% in some tets
    co.mergeDebris = false;  // and slivers that touch no neighbour's side: free pieces below one tet
    CutEngine eng(co);
    // A vertical edge at x = 0.43 moving along +y.
    auto edgeAt = [](double y) { return BladeEdge{{0.43, y, -0.2}, {0.43, y, 1.2}}; };
    double y = -0.1;
    for (; y < 0.5; y += 0.05) eng.sweep(m, s, edgeAt(y), edgeAt(y + 0.05));
    EXPECT_EQ(piecesAscending(m).size(), 1u);  // the blade stopped inside: pending, not separated
    EXPECT_GT(eng.pendingElements(), 0);
    for (; y < 1.1; y += 0.05) eng.sweep(m, s, edgeAt(y), edgeAt(y + 0.05));
    const auto pieces = piecesAscending(m);
    ASSERT_EQ(pieces.size(), 2u);
    EXPECT_NEAR(pieces[0], 0.43, 1e-12);
    EXPECT_EQ(eng.pendingElements(), 0);
    EXPECT_EQ(eng.cuts(), 1);           // one stroke, one cut id
    EXPECT_EQ(eng.strokeRegions(), 1);  // a straight translation is one parallelogram
}

// The broad phase only offers the elements near the blade; tissue that has moved out of its reach
// (here: every element above z = 0.25, never offered) is still cut where the swept area covers it,
// through the face neighbours of the elements split. Offered only the low layer, the engine used to
// leave the body one piece.
TEST(Xfem, BladeSweepReachesTissueAwayFromTheBlade) {
    Model m = unitBox(4);
    State s = makeState(m);
    CutOptions co;
    co.minFraction = 0;
    co.mergeDebris = false;
    CutEngine eng(co);
    std::vector<int> low;
    for (int e = 0; e < m.elements(); ++e) {
        double zmin = 1;
        for (int a = 0; a < 4; ++a) zmin = std::min(zmin, m.X(2, m.tets(a, e)));
        if (zmin < 0.25 - 1e-9) low.push_back(e);
    }
    ASSERT_LT(low.size(), static_cast<size_t>(m.elements()) / 3);
    auto edgeAt = [](double y) { return BladeEdge{{0.43, y, -0.2}, {0.43, y, 1.2}}; };
    for (double y = -0.1; y < 1.1; y += 0.05) eng.sweep(m, s, edgeAt(y), edgeAt(y + 0.05), &low);
    const auto pieces = piecesAscending(m);
    ASSERT_EQ(pieces.size(), 2u);
    EXPECT_NEAR(pieces[0], 0.43, 1e-12);
    EXPECT_EQ(eng.pendingElements(), 0);
}

// A blade step updates the incidence and the masses of the nodes it changed only; they must be
// what a full rebuild gives, bit for bit, after every step of a stroke that splits, drops slivers
// and copies nodes.
TEST(Xfem, BladeStepsUpdateIncidenceAndMassesAsAFullRebuild) {
    Model m = unitBox(5);
    State s = makeState(m);
    CutEngine eng;
    auto edgeAt = [](double t) { return BladeEdge{{0.37 + 0.1 * t, t, -0.2}, {0.37 + 0.1 * t, t + 0.3, 1.2}}; };
    int steps = 0, copies = 0;
    for (double t = 1.2; t > -0.5; t -= 0.04) {
        const CutResult r = eng.sweep(m, s, edgeAt(t), edgeAt(t - 0.04));
        if (!r.changed()) continue;
        ++steps;
        copies += static_cast<int>(r.newNodes.size());
        Model full = m;
        buildIncidence(full);
        updateMasses(full);
        ASSERT_LE(m.nodeSlots.size(), 6 * static_cast<size_t>(m.elements()) + 1024) << "step " << steps;
        const std::vector<std::uint8_t> virt = eng.virtualNodes(m);  // and one node's flag from its rows
        for (int i = 0; i < m.nodes(); ++i) {
            ASSERT_EQ(eng.isVirtualNode(m, i), virt.empty() ? false : virt[static_cast<size_t>(i)] != 0)
                << "node " << i << " step " << steps;
            const std::span<const int> a = full.slotsOf(i), b = m.slotsOf(i);
            ASSERT_TRUE(std::equal(a.begin(), a.end(), b.begin(), b.end())) << "node " << i << " step " << steps;
            ASSERT_EQ(full.mass(i), m.mass(i)) << "node " << i << " step " << steps;
            ASSERT_EQ(full.invMass(i), m.invMass(i)) << "node " << i << " step " << steps;
        }
    }
    EXPECT_GT(steps, 5);
    EXPECT_GT(copies, 0);
    EXPECT_EQ(piecesAscending(m).size(), 2u);
    const std::vector<std::uint8_t> virt = eng.virtualNodes(m);
    EXPECT_GT(std::count(virt.begin(), virt.end(), 1), 0);  // the check above saw virtual nodes
}

// A blade at rest sweeps no new area: it splits nothing, even where the tissue it entered has
// moved under the area swept before (rounding-level motion from keyframe interpolation included).
TEST(Xfem, BladeAtRestCutsNothing) {
    Model m = unitBox(4);
    State s = makeState(m);
    CutEngine eng;
    auto edgeAt = [](double y) { return BladeEdge{{0.43, y, -0.2}, {0.43, y, 1.2}}; };
    for (double y = -0.1; y < 0.5; y += 0.05) eng.sweep(m, s, edgeAt(y), edgeAt(y + 0.05));
    ASSERT_GT(eng.pendingElements(), 0);
    const int E = m.elements();
    s.x.row(1).array() -= 0.3;  // the body slides along -y, under the swept area
    const BladeEdge still = edgeAt(0.5);
    BladeEdge noisy = still;
    noisy.a.y() = std::nextafter(noisy.a.y(), 1.0);
    EXPECT_EQ(eng.sweep(m, s, still, still).crossed, 0);
    EXPECT_EQ(eng.sweep(m, s, still, noisy).crossed, 0);
    EXPECT_EQ(m.elements(), E);
    // moving on, it splits what the swept area now covers
    EXPECT_GT(eng.sweep(m, s, still, edgeAt(0.55)).crossed, 0);
}

TEST(Xfem, BladeSweepMergesOnlyStraightStretches) {
    // An edge along z in the plane x = 0.43: down along -y, then diagonally along (-y, +z), then
    // back up the diagonal. The union of the first two is not convex, so each stretch is its own
    // region however many steps it takes; a reversal and a turning edge are never merged.
    Model m = unitBox(4);
    State s = makeState(m);
    CutEngine eng;
    auto edgeAt = [](double y, double dz) { return BladeEdge{{0.43, y, -0.2 + dz}, {0.43, y, 1.2 + dz}}; };
    const int n = 10;
    for (int k = 0; k < n; ++k) eng.sweep(m, s, edgeAt(1.2 - 0.05 * k, 0), edgeAt(1.2 - 0.05 * (k + 1), 0));
    EXPECT_EQ(eng.strokeRegions(), 1);
    for (int k = 0; k < n; ++k)
        eng.sweep(m, s, edgeAt(0.7 - 0.05 * k, 0.03 * k), edgeAt(0.7 - 0.05 * (k + 1), 0.03 * (k + 1)));
    EXPECT_EQ(eng.strokeRegions(), 2);
    for (int k = n; k > 0; --k)
        eng.sweep(m, s, edgeAt(0.7 - 0.05 * k, 0.03 * k), edgeAt(0.7 - 0.05 * (k - 1), 0.03 * (k - 1)));
    EXPECT_EQ(eng.strokeRegions(), 3);
    const BladeEdge e = edgeAt(0.7, 0);
    eng.sweep(m, s, e, BladeEdge{{0.43, 0.6, -0.2}, e.b});
    EXPECT_EQ(eng.strokeRegions(), 4);
    EXPECT_EQ(eng.cuts(), 1);
}

TEST(Xfem, EnrichmentLumpingKeepsTimeStepOnSlivers) {
    // A cut 1e-6 beyond a node layer leaves slivers of ~1e-6 volume fraction.
    const double uncut = [] {
        Model m = unitBox(3);
        return 2.0 / std::sqrt(test::denseLambdaMax(m));
    }();
    std::map<MassLumping, double> dt;
    for (MassLumping l : {MassLumping::RowSum, MassLumping::WeightedDiagonal, MassLumping::Enrichment}) {
        Model m = unitBox(3);
        State s = makeState(m);
        CutEngine eng({l, 1e-10});
        const CutResult r = eng.cut(m, s, plane({1.0 / 3 + 1e-6, 0, 0}, {1, 0, 0}));
        EXPECT_GT(r.split, 0);
        EXPECT_LT(m.fraction.minCoeff(), 1e-4);
        EXPECT_NEAR(m.mass.sum(), 1000.0, 1e-9 * 1000.0);  // sides below 1e-10 are dropped
        dt[l] = 2.0 / std::sqrt(test::denseLambdaMax(m));
        std::printf("lumping %-17s dt after the sliver cut = %.4g of the uncut %.4g s\n", lumpingName(l), dt[l] / uncut,
                    uncut);
    }
    // Enrichment: every virtual element keeps its parent's eigenvalues; the others collapse.
    EXPECT_GE(dt[MassLumping::Enrichment], 0.9 * uncut);
    EXPECT_LT(dt[MassLumping::RowSum], 0.1 * uncut);
}

// A plane cutting off the corner x + y + z > 2.2 of a unit cube of 6 Kuhn tets (all six hold that
// corner) leaves a free piece of 0.8^3 / 6 = 0.0853 m^3, half of one tet (1/6): debris, fused back
// to the sides it was cut from. The fused pairs act as their parents, so the exact step is the
// uncut cube's and the model is one piece; mass and volume are kept. Without fusing it falls off.
TEST(Xfem, PieceBelowOneElementIsFusedBack) {
    for (const bool fuse : {true, false}) {
        Model m = unitBox(1);
        test::fixBelow(m, 0, 1e-9);
        const double uncut = 2.0 / std::sqrt(test::denseLambdaMax(m));
        State s = makeState(m);
        CutOptions co;
        co.mergeDebris = fuse;
        CutEngine eng(co);
        const CutResult r = eng.cut(m, s, plane({2.2 / 3, 2.2 / 3, 2.2 / 3}, {1, 1, 1}));
        EXPECT_EQ(r.split, 6);
        EXPECT_EQ(r.merged, fuse ? 1 : 0);
        EXPECT_NEAR(r.volumeAfter, 1.0, 1e-12);
        EXPECT_NEAR(m.mass.sum(), 1000.0, 1e-9);
        const auto pieces = piecesAscending(m);
        if (fuse) {
            ASSERT_EQ(pieces.size(), 1u);
            EXPECT_NEAR(2.0 / std::sqrt(test::denseLambdaMax(m)), uncut, 1e-9 * uncut);
        } else {
            ASSERT_EQ(pieces.size(), 2u);
            EXPECT_NEAR(pieces[0], 0.8 * 0.8 * 0.8 / 6, 1e-12);
        }
        // A second cut, x > 0.9, through the fused elements: they are not cut again, and its
        // slab (0.1 m^3, below one tet too) is fused back in turn.
        const CutResult r2 = eng.cut(m, s, plane({0.9, 0.5, 0.5}, {1, 0, 0}));
        EXPECT_GT(r2.crossed, 0);
        EXPECT_NEAR(r2.volumeAfter, 1.0, 1e-12);
        if (fuse) {
            EXPECT_EQ(r2.merged, 1);
            EXPECT_EQ(piecesAscending(m).size(), 1u);
        }
    }
}

TEST(Xfem, CutPieceFallsFreely) {
    // Bar fixed at x = 0, cut at x = 0.5: the free half falls with g, the fixed half holds.
    Model m = buildModel(test::boxMesh(1, 0.2, 0.2, 10, 2, 2), Material{});
    test::fixBelow(m, 0, 1e-9);
    m.gravity = Eigen::Vector3d(0, 0, -9.81);
    State s = makeState(m);
    CutOptions co;
    co.lightShare = 0;  // their damping is not momentum-conserving (measured: 3.5e-5 of the mean velocity here)
    CutEngine eng(co);
    eng.cut(m, s, plane({0.55, 0, 0}, {1, 0, 0}));
    Stepper st;
    StepOptions opt;
    opt.dt = 1e-4;
    for (int k = 0; k < 1000; ++k) st.step(m, s, opt);
    ASSERT_TRUE(s.flags.ok());
    // Mass-weighted mean z velocity of the free piece: -g t (its internal forces cancel).
    const std::vector<int> piece = pieceOfNode(m);
    int tip = 0;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.X(0, i) > 0.999) tip = piece[i];
    double mv = 0, mm = 0;
    for (int i = 0; i < m.nodes(); ++i)
        if (piece[i] == tip) {
            mv += m.mass(i) * s.v(2, i);
            mm += m.mass(i);
        }
    EXPECT_NEAR(mv / mm, -9.81 * 0.1, 1e-6);
}

}  // namespace
}  // namespace cutsim
