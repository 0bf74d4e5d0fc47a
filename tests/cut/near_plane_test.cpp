// The local improvement after a conforming cut (cut/baselines.hpp improveNearPlane) on its
// budget: the bar of `cutsim bench cutstep` through its four planes.
#include "cut/baselines.hpp"
#include "fem/tet.hpp"
#include "mesh/generate.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace cutsim {
namespace {

std::vector<CutPlane> barPlanes() {
    std::vector<CutPlane> planes = {{{0.023, 0.01, 0.01}, {1, 0.15, 0.05}},
                                    {{0.047, 0.01, 0.01}, {1, -0.1, 0.2}},
                                    {{0.068, 0.01, 0.01}, {1, 0.2, -0.1}},
                                    {{0.086, 0.01, 0.01}, {1, 0.05, 0.25}}};
    for (CutPlane& p : planes) p.normal.normalize();
    return planes;
}

// Within its budget the improvement never inverts an element, never lowers the whole mesh's exact
// step under the unimproved cut's, frees at most the cap's nodes (plus the rest of the element
// that reached it), and gives the same mesh every time.
TEST(NearPlane, BudgetedKeepsTheCutsStepAndIsDeterministic) {
    const Material mat;
    TetMesh mesh = boxMesh(0.1, 0.02, 0.02, 10, 2, 2);
    NearPlaneOptions o = NearPlaneOptions::budgeted(exactDtOf(mesh, mat));
    o.maxSeconds = 1e9;  // the budget is the work alone, so the result does not depend on the machine
    int raised = 0;
    for (const CutPlane& p : barPlanes()) {
        mesh = conformingCut(mesh, p).mesh;
        const double dtCut = exactDtOf(mesh, mat);
        TetMesh again = mesh;
        const NearPlaneReport r = improveNearPlane(mesh, p, mat, o);
        improveNearPlane(again, p, mat, o);
        EXPECT_EQ(again.X, mesh.X);
        EXPECT_EQ(again.tets, mesh.tets);
        for (int e = 0; e < mesh.elements(); ++e) ASSERT_GT(tetSignedVolume(mesh, e), 0.0) << e;
        const double dt = exactDtOf(mesh, mat);
        EXPECT_GE(dt, dtCut * (1 - 1e-9));
        raised += dt > 1.05 * dtCut;
        EXPECT_GT(r.critical, 0);  // a cut off the lattice leaves elements under the uncut step
        EXPECT_LE(r.freeNodes, o.maxFreeNodes + 3);
        EXPECT_GE(r.dtAfter, r.dtBefore);
        // a node's descent and the last round's check may end past the budget, not by a round
        EXPECT_LE(r.problems, o.maxProblems + o.maxProblems / 10);
    }
    EXPECT_GE(raised, 2);
}

}  // namespace
}  // namespace cutsim
