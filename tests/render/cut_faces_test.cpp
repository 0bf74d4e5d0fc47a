// A cut's faces in frames: seen from both sides, the two pieces' cut faces are closed, smooth and in
// the cut material, with nothing of the outer surface or the inside showing through.
#include "cut/xfem.hpp"
#include "golden.hpp"
#include "renderer.hpp"
#include "snapshot/snapshot.hpp"
#include "fem/integrate.hpp"
#include "mesh/embedding.hpp"
#include "test_support.hpp"
#include "util/union_find.hpp"

#include <gtest/gtest.h>

namespace cutsim {
namespace {

using render::Image;
using render::Renderer;
using render::RenderOptions;

// A 4 x 2 x 1 cm box cut through by a blade stroke in an oblique plane that passes close to nodes
// (so sides are dropped), the piece on the plane's positive side moved 5 cm along its normal; the
// surface seen from `eye` looking at `target`.
Image cutBox(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, int* dropped = nullptr,
             int* cutFaces = nullptr) {
    const TetMesh mesh = test::boxMesh(0.04, 0.02, 0.01, 8, 4, 2);
    Model m = buildModel(mesh, Material{});
    State s = makeState(m);
    CutEngine eng;
    // A scalpel edge across the box (along y, tilted) swept down through it in steps: the stroke's
    // plane holds the edge and its motion, normal (1, 0.25, 0.1) up to the tilt.
    const Eigen::Vector3d n = Eigen::Vector3d(1, 0.25, 0.1).normalized(), down(-0.1, 0, 1);
    const Eigen::Vector3d along = n.cross(down).normalized(), centre(0.0205, 0.01, 0.005);
    const Eigen::Vector3d motion = along.cross(n).normalized();  // in the plane, across the edge
    auto edgeAt = [&](double t) {
        const Eigen::Vector3d mid = centre + t * motion;
        return BladeEdge{mid - 0.05 * along, mid + 0.05 * along};
    };
    CutResult r;
    for (double t = -0.03; t < 0.03; t += 0.01) {
        const CutResult step = eng.sweep(m, s, edgeAt(t), edgeAt(t + 0.01));
        r.dropped += step.dropped;
    }
    CutSurface c;
    c.point = centre;
    c.normal = n;
    if (dropped) *dropped = r.dropped;
    UnionFind uf = elementPieces(m.tets, m.nodes());
    EXPECT_EQ(pieceVolumes(m).size(), 2u) << "the stroke must go through";
    Eigen::VectorXd sideSum = Eigen::VectorXd::Zero(m.nodes());
    for (int i = 0; i < m.nodes(); ++i) sideSum[uf.find(i)] += (m.X.col(i) - c.point).dot(c.normal) > 0 ? 1 : -1;
    Eigen::Matrix3Xd x = m.X;
    for (int i = 0; i < m.nodes(); ++i)
        if (sideSum[uf.find(i)] > 0) x.col(i) += 0.05 * c.normal;
    TetMesh cut;
    cut.X = m.X;
    cut.tets = m.tets;
    MeshSnapshot ms = snapshotFromSurface(cut, x, eng.surface(m));
    if (cutFaces) *cutFaces = static_cast<int>(std::count(ms.snap.cutFace.begin(), ms.snap.cutFace.end(), 1));
    ms.snap.camera.eye = eye;
    ms.snap.camera.target = target;
    ms.snap.camera.up = Eigen::Vector3d::UnitZ();
    ms.snap.camera.fovY = 50;
    RenderOptions o;
    o.width = 320;
    o.height = 180;
    o.floor = false;
    o.legend = false;
    return Renderer(o).render(ms.snap);
}

TEST(RenderGolden, BladeCutFacesSeenFromBothSides) {
    int dropped = 0, cutFaces = 0;
    // The kept piece's cut face (facing +x), then the moved piece's (facing -x).
    const Image front = cutBox({0.042, 0.028, 0.016}, {0.019, 0.01, 0.004}, &dropped, &cutFaces);
    EXPECT_GT(dropped, 0) << "the plane must drop slivers for this test";
    EXPECT_GT(cutFaces, 0);
    test::expectGolden("cut_faces_front", front, {5, 0.001});
    test::expectGolden("cut_faces_back", cutBox({0.05, -0.006, 0.016}, {0.07, 0.013, 0.006}), {5, 0.001});
}

}  // namespace
}  // namespace cutsim
