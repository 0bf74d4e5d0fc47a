// Four-plane liver cut (thesis sec. 5.2): exact step after each cut for subdivision and remesh.
// Slow (a global eigen-solve per cut on meshes of thousands of nodes): label stress.
#include "cut/baselines.hpp"
#include "cut/remesh.hpp"
#include "mesh/io.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cstdio>

namespace cutsim {
namespace {

// Four parallel planes across the liver's longest bounding-box axis at 20/40/60/80 %, as the
// thesis cuts its livers in four consecutive incisions (sec. 5.2, Fig. 5.14).
std::vector<CutPlane> liverPlanes(const TetMesh& liver) {
    const Eigen::Vector3d lo = liver.X.rowwise().minCoeff(), hi = liver.X.rowwise().maxCoeff();
    int axis = 0;
    (hi - lo).maxCoeff(&axis);
    std::vector<CutPlane> planes;
    for (const double f : {0.2, 0.4, 0.6, 0.8}) {
        CutPlane p;
        p.point = lo + f * (hi - lo);
        p.normal = Eigen::Vector3d::Unit(axis);
        planes.push_back(p);
    }
    return planes;
}

TEST(BaselinesStress, LiverDtAfterFourPlaneCuts) {
    ReadOptions ro;
    ro.scale = 0.0254;  // assets/scenes/demo.json
    const TetMesh liver = readTetMesh(test::source("assets/meshes/liver.msh"), ro);
    const std::vector<CutPlane> planes = liverPlanes(liver);

    const double dt0 = exactDtOf(liver);
    const std::vector<double> sub = dtAfterPlaneCuts(liver, planes, CutMethod::Subdivision);
    ASSERT_EQ(sub.size(), 4u);
    std::printf("liver %d nodes %d tets, uncut dt %.4f ms\n", liver.nodes(), liver.elements(), 1e3 * dt0);
    std::printf("subdivision: dt after cuts 1-4 [ms]:");
    for (const double d : sub) std::printf(" %.4f", 1e3 * d);
    std::printf("\n");
    // The thesis's observation (Table 5.4): the cuts lower the step.
    EXPECT_LT(sub.back(), dt0);

    if (!haveTetGen()) GTEST_SKIP() << "built without TetGen";
    // Remeshing the uncut liver alone already costs most of the step: TetGen must keep the
    // original surface triangles, and its Steiner points near them make small tets.
    const RemeshResult whole = remeshPieces(liver);
    std::printf("remesh of the uncut liver: %d nodes %d tets, dt %.4f ms\n", whole.mesh.nodes(), whole.mesh.elements(),
                1e3 * exactDtOf(whole.mesh));
    const std::vector<double> rem = dtAfterPlaneCuts(liver, planes, CutMethod::Remesh);
    ASSERT_EQ(rem.size(), 4u);
    std::printf("remesh: dt after cuts 1-4 [ms]:");
    for (const double d : rem) std::printf(" %.4f", 1e3 * d);
    std::printf("\n");
    for (const double d : rem) EXPECT_GT(d, 0);
    EXPECT_LT(rem.back(), dt0);
}

}  // namespace
}  // namespace cutsim
