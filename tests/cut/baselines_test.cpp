// Table 6.1 baselines (cut/baselines.hpp): the bar cut by subdivision and by remeshing, and the
// four-plane liver cut (thesis sec. 5.2), measured by the exact critical step.
#include "cut/baselines.hpp"
#include "cut/remesh.hpp"
#include "fem/model.hpp"
#include "mesh/io.hpp"
#include "test_support.hpp"
#include "timestep/timestep.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

namespace cutsim {
namespace {

TEST(Baselines, BarTable61) {
    const BarOptions o;
    const TetMesh bar = barMesh(o);
    EXPECT_EQ(bar.nodes(), 90);  // the thesis's bar has 90 nodes
    EXPECT_EQ(bar.elements(), 216);
    // Uncut step from an independent dense eigen-solve of the same model.
    const Model model = buildModel(bar, o.material);
    const double dtDense = 2 / std::sqrt(test::denseLambdaMax(model));
    BarOptions run = o;
    if (!haveTetGen()) GTEST_SKIP() << "built without TetGen";
    const std::vector<BaselineRow> rows = barCutBaselines(run);
    ASSERT_EQ(rows.size(), 8u);
    std::printf("kept  method       nodes  tets  dt_exact [ms]\n");
    for (const BaselineRow& r : rows)
        std::printf("%3.0f%%  %-11s  %5d  %4d  %.4f\n", 100 * r.kept, r.method.c_str(), r.nodes, r.elements,
                    1e3 * r.dtExact);
    for (int k = 0; k < 2; ++k) {
        EXPECT_EQ(rows[k].kept, 1.0);
        EXPECT_EQ(rows[k].nodes, 90);
        EXPECT_EQ(rows[k].elements, 216);
        EXPECT_NEAR(rows[k].dtExact, dtDense, 1e-7 * dtDense);
    }
    EXPECT_EQ(rows[0].method, "subdivision");
    EXPECT_EQ(rows[1].method, "remesh");
    // Thesis observation: the subdivision cut at 75% lowers the step.
    EXPECT_EQ(rows[2].kept, 0.75);
    EXPECT_LT(rows[2].dtExact, rows[0].dtExact);
}

}  // namespace
}  // namespace cutsim

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

TEST(Baselines, LiverFourPlaneCuts) {
    ReadOptions ro;
    ro.scale = 0.0254;  // assets/scenes/demo.json
    const TetMesh liver = readTetMesh(test::source("assets/meshes/liver.msh"), ro);
    const std::vector<CutPlane> planes = liverPlanes(liver);
    const double v0 = totalVolume(liver);

    // Without snapping the split conserves the volume exactly; every cut adds a piece.
    ConformingOptions exact;
    exact.snapFraction = 0;
    const ConformingResult cut = conformingCuts(liver, planes, exact);
    EXPECT_NEAR(cut.report.volumeAfter, v0, 1e-9 * v0);
    EXPECT_GT(cut.report.minVolume, 0);
    EXPECT_GE(connectedPieces(cut.mesh), 5);
    // Conformity: boundary faces off the planes are pieces of the liver's surface (same total
    // area, so no hanging node left an inner face open), and on each plane both sides show the
    // same cross-section area.
    auto faceArea = [](const TetMesh& m, const Eigen::Matrix3Xi& F, Eigen::Index f, Eigen::Vector3d* normal) {
        const Eigen::Vector3d c = (m.X.col(F(1, f)) - m.X.col(F(0, f))).cross(m.X.col(F(2, f)) - m.X.col(F(0, f)));
        if (normal) *normal = c.normalized();
        return 0.5 * c.norm();
    };
    const Eigen::Matrix3Xi F0 = boundaryFaces(liver), F1 = boundaryFaces(cut.mesh);
    double a0 = 0, aOff = 0;
    std::vector<double> up(planes.size(), 0), down(planes.size(), 0);
    for (Eigen::Index f = 0; f < F0.cols(); ++f) a0 += faceArea(liver, F0, f, nullptr);
    for (Eigen::Index f = 0; f < F1.cols(); ++f) {
        Eigen::Vector3d nf;
        const double a = faceArea(cut.mesh, F1, f, &nf);
        int on = -1;
        for (size_t k = 0; k < planes.size() && on < 0; ++k) {
            bool all = true;
            for (int j = 0; j < 3; ++j)
                all = all && std::abs(planes[k].normal.dot(cut.mesh.X.col(F1(j, f)) - planes[k].point)) < 1e-12;
            if (all) on = static_cast<int>(k);
        }
        if (on < 0)
            aOff += a;
        else
            (nf.dot(planes[on].normal) > 0 ? up : down)[on] += a;
    }
    EXPECT_NEAR(aOff, a0, 1e-9 * a0);
    for (size_t k = 0; k < planes.size(); ++k) {
        EXPECT_GT(up[k], 0);
        EXPECT_NEAR(up[k], down[k], 1e-9 * a0) << "plane " << k;
    }

    // With snapping (threshold 0.1): surface nodes move, the volume barely; nothing inverts.
    const ConformingResult snapped = conformingCuts(liver, planes);
    EXPECT_GT(snapped.report.snappedNodes, 0);
    EXPECT_NEAR(snapped.report.volumeAfter, v0, 0.02 * v0);
    for (int e = 0; e < snapped.mesh.elements(); ++e) ASSERT_GT(tetSignedVolume(snapped.mesh, e), 0);
}

}  // namespace
}  // namespace cutsim
