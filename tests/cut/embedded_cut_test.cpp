// Cutting an object given by its surface (mesh intersection): the embedded surface split by the
// cut, and cut faces only inside it, not over the lattice cells it crosses.
#include "cut/xfem.hpp"
#include "embed/mi.hpp"
#include "fem/state.hpp"
#include "mesh/embedding.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace cutsim {
namespace {

// The box [0.1, 0.9] x [0.1, 0.7] x [0.1, 0.45] (12 triangles) in the lattice of 0.25 m cells from
// the origin: every face of the box crosses cells. Cut by the plane x = c in the middle of a cell
// column, so every Kuhn tet keeps at least 1/8 on each side (no side is merged as a sliver).
constexpr double kC = 0.625;  // [m]
const Eigen::Vector3d kLo(0.1, 0.1, 0.1), kHi(0.9, 0.7, 0.45);

struct CutBox {
    MiResult mi;
    State s;
    CutEngine eng;
    CutResult r;
};

void cutBox(CutBox& b) {
    MiOptions o;
    o.h = 0.25;
    o.latticeCells = Eigen::Vector3i(4, 3, 2);
    o.latticeOrigin = Eigen::Vector3d::Zero();
    b.mi = buildMi(boxSurface(kLo, kHi), Material{}, o);
    b.s = makeState(b.mi.model);
    CutSurface c;
    c.point = Eigen::Vector3d(kC, 0, 0);
    c.normal = Eigen::Vector3d::UnitX();
    b.r = b.eng.cut(b.mi.model, b.s, c);
}

struct Areas {
    double left = 0, right = 0;        // non-cut triangles by centroid side [m^2]
    double capPlus = 0, capMinus = 0;  // cut triangles with normal +x (left piece's) and -x [m^2]
    double capOffPlane = 0;            // largest |x - c| of a cut-face vertex [m]
    double capOutside = 0;             // largest distance of a cut-face vertex outside the box's section [m]
};

Areas areasOf(const EmbeddedSurface& es, const Model& m) {
    Eigen::Matrix3Xd p;
    embeddedPositions(es, m.tets, m.X, p);
    Areas a;
    for (int f = 0; f < es.faces(); ++f) {
        const Eigen::Vector3d x0 = p.col(es.triangles(0, f)), x1 = p.col(es.triangles(1, f)), x2 = p.col(es.triangles(2, f));
        const Eigen::Vector3d n = 0.5 * (x1 - x0).cross(x2 - x0);
        if (es.cutFace[static_cast<size_t>(f)]) {
            (n.x() > 0 ? a.capPlus : a.capMinus) += n.norm();
            for (const Eigen::Vector3d& x : {x0, x1, x2}) {
                a.capOffPlane = std::max(a.capOffPlane, std::abs(x.x() - kC));
                for (int d = 1; d < 3; ++d)
                    a.capOutside = std::max({a.capOutside, kLo[d] - x[d], x[d] - kHi[d]});
            }
        } else {
            ((x0 + x1 + x2).x() / 3 < kC ? a.left : a.right) += n.norm();
        }
    }
    return a;
}

TEST(EmbeddedCut, BoxSurfaceSplitAndCapsInsideTheBox) {
    CutBox b;
    cutBox(b);
    ASSERT_GT(b.r.split, 0);
    ASSERT_EQ(b.r.dropped, 0);
    const EmbeddedSurface es = b.eng.surface(b.mi.model, b.mi.surface, 4);
    const Areas a = areasOf(es, b.mi.model);
    // The box's own faces, split at x = c: left 2 (0.525 (0.6 + 0.35)) + 0.21, right 2 (0.275 (0.6 + 0.35)) + 0.21.
    EXPECT_NEAR(a.left, 1.2075, 1e-9);
    EXPECT_NEAR(a.right, 0.7325, 1e-9);
    // Each side's cut face is the box's cross-section 0.6 x 0.35 = 0.21 m^2 (the lattice's is
    // 0.75 x 0.5 = 0.375); its edge is resolved to a sub-triangle (cell edge / 16 = 0.016 m).
    EXPECT_NEAR(a.capPlus, 0.21, 0.01);
    EXPECT_NEAR(a.capMinus, 0.21, 0.01);
    EXPECT_LT(a.capOffPlane, 1e-9);
    EXPECT_LT(a.capOutside, 0.25 * std::sqrt(2.0) / 16);
    for (int v = 0; v < es.vertices(); ++v) {
        EXPECT_NEAR(es.weights.col(v).sum(), 1.0, 1e-12);
        EXPECT_GE(es.weights.col(v).minCoeff(), -1e-9);
    }
    // Finer cap sampling: closer to the section.
    const Areas coarse = areasOf(b.eng.surface(b.mi.model, b.mi.surface, 1), b.mi.model);
    const Areas fine = areasOf(b.eng.surface(b.mi.model, b.mi.surface, 5), b.mi.model);
    EXPECT_NEAR(coarse.left, 1.2075, 1e-9);
    EXPECT_LT(std::abs(fine.capPlus - 0.21), std::abs(coarse.capPlus - 0.21));
    EXPECT_NEAR(fine.capPlus, 0.21, 3e-3);
}

TEST(EmbeddedCut, EveryTriangleRidesTheElementOfItsSide) {
    // Move each side of the cut apart by d: every control point of an element on the left moves
    // by -d, on the right by +d. A surface vertex must move with the side its rest point is on.
    CutBox b;
    cutBox(b);
    const Model& m = b.mi.model;
    const EmbeddedSurface es = b.eng.surface(m, b.mi.surface);
    const double d = 0.05;
    Eigen::Matrix3Xd x = m.X;
    for (int n = 0; n < m.nodes(); ++n) {
        const int o = b.eng.originalNode(n);
        const double side = m.X(0, o) > kC ? 1.0 : -1.0;
        x(0, n) += (n == o ? side : -side) * d;  // a copy stands for its node on the far side
    }
    Eigen::Matrix3Xd rest, moved;
    embeddedPositions(es, m.tets, m.X, rest);
    embeddedPositions(es, m.tets, x, moved);
    int checked = 0;
    for (int f = 0; f < es.faces(); ++f) {
        Eigen::Vector3d mid = Eigen::Vector3d::Zero();
        for (int i = 0; i < 3; ++i) mid += rest.col(es.triangles(i, f)) / 3;
        const Eigen::Vector3d n = (rest.col(es.triangles(1, f)) - rest.col(es.triangles(0, f)))
                                      .cross(rest.col(es.triangles(2, f)) - rest.col(es.triangles(0, f)));
        // a cut face lies on the plane: its side is the one it faces away from
        const bool left = es.cutFace[static_cast<size_t>(f)] ? n.x() > 0 : mid.x() < kC;
        const double want = left ? -d : d;
        for (int i = 0; i < 3; ++i) {
            const int v = es.triangles(i, f);
            ASSERT_NEAR(moved(0, v) - rest(0, v), want, 1e-9) << "triangle " << f;
            ASSERT_NEAR((moved.col(v) - rest.col(v)).tail<2>().norm(), 0.0, 1e-9);
        }
        ++checked;
    }
    EXPECT_GT(checked, 12);
}

TEST(EmbeddedCut, UncutEngineKeepsTheSurface) {
    MiOptions o;
    o.cells = 3;
    const MiResult mi = buildMi(boxSurface(kLo, kHi), Material{}, o);
    CutEngine eng;
    eng.prepare(mi.model);
    const EmbeddedSurface es = eng.surface(mi.model, mi.surface);
    EXPECT_EQ(es.faces(), mi.surface.faces());
    EXPECT_EQ(es.vertices(), mi.surface.vertices());
    for (int f = 0; f < es.faces(); ++f)
        for (int i = 0; i < 3; ++i) {
            const int v = es.triangles(i, f), w = mi.surface.triangles(i, f);
            EXPECT_EQ(es.element[static_cast<size_t>(v)], mi.surface.element[static_cast<size_t>(w)]);
            EXPECT_EQ(es.weights.col(v), mi.surface.weights.col(w));
        }
}

} // namespace
} // namespace cutsim
