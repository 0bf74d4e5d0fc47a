// Renderer: exact pixels where they can be computed, golden images for whole scenes.
#include "colormap.hpp"
#include "egl_context.hpp"
#include "golden.hpp"
#include "renderer.hpp"
#include "snapshot/snapshot.hpp"
#include "bench/random_cuts.hpp"
#include "fem/integrate.hpp"
#include "mesh/io.hpp"
#include "test_support.hpp"
#include "timestep/analyzer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <algorithm>

namespace cutsim {
namespace {

using render::ColorMapKind;
using render::Image;
using render::Renderer;
using render::RenderOptions;

// Golden frames stay small so the repository stays light.
constexpr int kGoldenW = 320, kGoldenH = 180;

RenderOptions goldenOptions() {
    RenderOptions o;
    o.width = kGoldenW;
    o.height = kGoldenH;
    return o;
}

// A 4 x 2 x 1 cm box, 8 x 4 x 2 cubes.
TetMesh scenebox() { return test::boxMesh(0.04, 0.02, 0.01, 8, 4, 2); }

// Per-element field: a smooth bump along x, so the colour map shows a gradient.
Eigen::VectorXd bumpField(const TetMesh& m) {
    Eigen::VectorXd f(m.elements());
    for (int e = 0; e < m.elements(); ++e) {
        Eigen::Vector3d c = Eigen::Vector3d::Zero();
        for (int a = 0; a < 4; ++a) c += 0.25 * m.X.col(m.tets(a, e));
        f[e] = std::sin(M_PI * c.x() / 0.04) * (1 + 10 * c.z());
    }
    return f;
}

// A few elements in the middle of the box, hidden under the surface.
std::vector<int> someCritical(const TetMesh& m) {
    std::vector<int> crit;
    for (int e = 0; e < m.elements(); ++e) {
        Eigen::Vector3d c = Eigen::Vector3d::Zero();
        for (int a = 0; a < 4; ++a) c += 0.25 * m.X.col(m.tets(a, e));
        if (std::abs(c.x() - 0.0225) < 0.002 && std::abs(c.y() - 0.0125) < 0.002 && c.z() < 0.005) crit.push_back(e);
    }
    return crit;
}

TEST(Render, ContextIsGl33Core) {
    render::EglContext ctx;
    EXPECT_FALSE(ctx.renderer().empty());
    EXPECT_FALSE(ctx.platform().empty());
}

TEST(Render, EmptyFrameIsTheClearColour) {
    RenderOptions o = goldenOptions();
    o.background = {12, 200, 77};
    Renderer r(o);
    const Image img = r.render(RenderSnapshot{});
    ASSERT_EQ(img.width, kGoldenW);
    ASSERT_EQ(img.height, kGoldenH);
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            auto p = img.pixel(x, y);
            ASSERT_EQ(p[0], 12);
            ASSERT_EQ(p[1], 200);
            ASSERT_EQ(p[2], 77);
            ASSERT_EQ(p[3], 255);
        }
}

// A quad far larger than the view, facing the camera, with a constant scalar.
RenderSnapshot screenQuad(double value, double lo, double hi, bool diverging) {
    RenderSnapshot s;
    s.positions.resize(3, 4);
    s.positions << -10, 10, 10, -10, -10, -10, 10, 10, 0, 0, 0, 0;
    s.triangles.resize(3, 2);
    s.triangles << 0, 0, 1, 2, 2, 3;
    s.scalar = Eigen::VectorXd::Constant(4, value);
    s.scalarMin = lo;
    s.scalarMax = hi;
    s.diverging = diverging;
    s.camera.eye = {0, 0, 1};
    s.camera.target = {0, 0, 0};
    s.camera.up = {0, 1, 0};
    return s;
}

// Unlit, a constant value at a control point gives exactly that control point's colour.
TEST(Render, ControlPointColourIsExact) {
    RenderOptions o = goldenOptions();
    o.lighting = false;
    o.floor = false;
    o.legend = false;
    Renderer r(o);
    struct Case {
        ColorMapKind kind;
        int point;
    };
    for (Case c :
         {Case{ColorMapKind::Sequential, 0}, Case{ColorMapKind::Sequential, 2}, Case{ColorMapKind::Sequential, 8},
          Case{ColorMapKind::Diverging, 1}, Case{ColorMapKind::Diverging, 2}}) {
        auto table = render::colorMapTable(c.kind);
        const double n = double(table.size() - 1);
        // Range [0, n]: value = index, so t * (n - 1) is an exact integer in float.
        const Image img = r.render(screenQuad(c.point, 0, n, c.kind == ColorMapKind::Diverging));
        const render::Rgb8 want = table[size_t(c.point)];
        for (auto [x, y] : {std::pair{0, 0}, {kGoldenW / 2, kGoldenH / 2}, {kGoldenW - 1, kGoldenH - 1}, {17, 101}}) {
            auto p = img.pixel(x, y);
            EXPECT_EQ(p[0], want.r) << "point " << c.point << " at " << x << "," << y;
            EXPECT_EQ(p[1], want.g);
            EXPECT_EQ(p[2], want.b);
        }
    }
}

// The legend bar shows the map: bottom = min, top = max, linear in between.
TEST(Render, LegendBarPixel) {
    RenderOptions o = goldenOptions();
    o.width = 640;
    o.height = 360;
    o.floor = false;
    Renderer r(o);
    RenderSnapshot s = screenQuad(0.5, 0, 1, false);
    s.positions *= 0.001;  // quad far from the legend's corner of the screen... and tiny
    s.scalarName = "value";
    const Image img = r.render(s);
    const render::PixelRect rect = r.legendRect();
    const int x = int(0.5f * (rect.x0 + rect.x1));
    for (int y : {int(rect.y0) + 3, int(0.5f * (rect.y0 + rect.y1)), int(rect.y1) - 3,
                  int(rect.y0 + 0.3f * (rect.y1 - rect.y0))}) {
        const double t = (rect.y1 - (y + 0.5)) / (rect.y1 - rect.y0);
        const auto want = render::colorMapLookup(ColorMapKind::Sequential, t);
        auto p = img.pixel(x, y);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(p[c], want[c] * 255, 2.0) << "row " << y << " channel " << c;
    }
}

TEST(Render, SnapshotOfBoxSurface) {
    const TetMesh m = test::boxMesh(1, 1, 1, 2, 3, 4);
    Eigen::VectorXd f = Eigen::VectorXd::Constant(m.elements(), 7.0);
    MeshSnapshotOptions so;
    so.elementValues = &f;
    so.wireframe = true;
    so.critical = {0, 5};
    const MeshSnapshot ms = snapshotFromTetMesh(m, so);
    // Each boundary square is two triangles; boundary nodes are all but the interior ones.
    EXPECT_EQ(ms.snap.faces(), 2 * 2 * (2 * 3 + 3 * 4 + 2 * 4));
    EXPECT_EQ(ms.snap.vertices(), 3 * 4 * 5 - 1 * 2 * 3);
    for (int v = 0; v < ms.snap.vertices(); ++v) EXPECT_DOUBLE_EQ(ms.snap.scalar[v], 7.0);
    EXPECT_LT(ms.snap.scalarMin, 7.0);
    EXPECT_GT(ms.snap.scalarMax, 7.0);
    EXPECT_EQ(ms.snap.criticalTets.cols(), 8);
    EXPECT_EQ(ms.snap.hud.criticalElements, 2);
    EXPECT_GT(ms.snap.edges.cols(), 0);
    EXPECT_TRUE(ms.snap.camera.target.isApprox(Eigen::Vector3d(0.5, 0.5, 0.5)));
}

// ---- golden scenes ----

TEST(RenderGolden, BoxWithField) {
    const TetMesh m = scenebox();
    const Eigen::VectorXd f = bumpField(m);
    MeshSnapshotOptions so;
    so.elementValues = &f;
    so.name = "bump";
    so.critical = someCritical(m);
    ASSERT_FALSE(so.critical.empty());
    Renderer r(goldenOptions());
    test::expectGolden("box_field", r.render(snapshotFromTetMesh(m, so).snap), {8, 0.01});
}

TEST(RenderGolden, BoxSagging) {
    const TetMesh m = scenebox();
    // Cantilever-like sag: fixed at x = 0, tip down by 1.2 thicknesses.
    Eigen::Matrix3Xd x = m.X;
    for (int i = 0; i < x.cols(); ++i) {
        const double s = x(0, i) / 0.04;
        x(2, i) -= 0.012 * s * s;
    }
    const Eigen::VectorXd f = bumpField(m);
    MeshSnapshotOptions so;
    so.elementValues = &f;
    so.name = "bump";
    so.wireframe = true;
    so.critical = someCritical(m);
    MeshSnapshot ms = snapshotFromTetMesh(m, x, so);
    ToolShape tool;
    tool.kind = ToolShape::Kind::Capsule;
    tool.position = {0.03, 0.01, 0.016};
    tool.size = {0.002, 0.004, 0};
    tool.orientation = Eigen::AngleAxisd(0.6, Eigen::Vector3d::UnitY());
    ms.snap.tools.push_back(tool);
    Renderer r(goldenOptions());
    test::expectGolden("box_sag", r.render(ms.snap), {8, 0.01});
}

TEST(RenderGolden, HudFrame) {
    const TetMesh m = scenebox();
    Eigen::VectorXd f = bumpField(m).array() - 0.5;
    MeshSnapshotOptions so;
    so.elementValues = &f;
    so.name = "stress";
    so.unit = "kPa";
    so.diverging = true;
    MeshSnapshot ms = snapshotFromTetMesh(m, so);
    ms.snap.cutFace[0] = ms.snap.cutFace[1] = 1;
    HudValues& h = ms.snap.hud;
    h.simTime = 0.125;
    h.dtUsed = 2.5e-5;
    h.dtCertified = 2.4e-5;
    h.stepsPerSecond = 41000;
    h.realTimeFactor = 1.025;
    h.cuts = 1;
    h.lines = {"scene: golden"};
    RenderOptions o = goldenOptions();
    o.width = 480;
    o.height = 270;
    o.hud = true;
    Renderer r(o);
    // The first frame already shows the HUD: the renderer runs ImGui's hidden first frame itself.
    test::expectGolden("hud", r.render(ms.snap), {8, 0.02});
}

// The SOFA liver as the demo scene has it: scale 0.0254, fixed at its back, gravity along -y.
Model goldenLiver() { return randomCutLiverModel(readTetMesh(test::data("tet/sofa_liver.msh")), kSceneLiverClampZ); }

// Coloured by each element's R1R step over dt = 0.9 of the exact limit; the five most critical
// elements (the smallest estimates) drawn through the surface.
MeshSnapshot liverTimestepSnapshot(const Model& m, const Eigen::Matrix3Xd& x) {
    TimestepAnalyzer ta(m);
    const double dt = 0.9 * ta.exact(m).dt;
    static Eigen::VectorXd ratio;
    ratio = ta.estimates().r1r / dt;
    std::vector<int> order(static_cast<size_t>(m.elements()));
    std::iota(order.begin(), order.end(), 0);
    std::partial_sort(order.begin(), order.begin() + 5, order.end(), [&](int a, int b) { return ratio[a] < ratio[b]; });
    MeshSnapshotOptions so;
    so.elementValues = &ratio;
    so.name = "element dt / dt";
    so.critical.assign(order.begin(), order.begin() + 5);
    TetMesh mesh;
    mesh.X = m.X;
    mesh.tets = m.tets;
    MeshSnapshot ms = snapshotFromTetMesh(mesh, x, so);
    ms.snap.scalarMin = 1;
    ms.snap.scalarMax = 2.5;
    return ms;
}

TEST(RenderGolden, LiverTimestepWithCriticalElements) {
    const Model m = goldenLiver();
    MeshSnapshot ms = liverTimestepSnapshot(m, m.X);
    ASSERT_GT(ms.snap.criticalTets.cols(), 0);
    Renderer r(goldenOptions());
    test::expectGolden("liver_timestep", r.render(ms.snap), {8, 0.01});
}

// The same liver after 0.2 s under gravity (symplectic Euler at 0.9 of the exact limit), with the HUD.
TEST(RenderGolden, LiverSaggingWithHud) {
    Model m = goldenLiver();
    State s = makeState(m);
    StepOptions opt;
    opt.dt = 0.9 * TimestepAnalyzer(m).exact(m).dt;
    Stepper stepper;
    while (s.time < 0.2) stepper.step(m, s, opt);
    ASSERT_TRUE(s.flags.ok());
    const double sag = (s.x - m.X).colwise().norm().maxCoeff();
    EXPECT_GT(sag, 0.005);  // visibly deformed: more than 5 mm at the free lobe
    MeshSnapshot ms = liverTimestepSnapshot(m, s.x);
    HudValues& h = ms.snap.hud;
    h.simTime = s.time;
    h.dtUsed = opt.dt;
    h.dtExact = opt.dt / 0.9;
    h.dtCertified = 0.349e-3;
    h.criticalElements = 5;
    h.lines = {"liver: 596 tets, 181 nodes"};
    // the object right of the HUD panel: camera moved left along the screen's horizontal
    Camera& c = ms.snap.camera;
    const Eigen::Vector3d right = (c.target - c.eye).cross(c.up).normalized();
    const Eigen::Vector3d shift = -0.12 * (c.target - c.eye).norm() * right;
    c.eye += shift;
    c.target += shift;
    RenderOptions o = goldenOptions();
    o.width = 480;
    o.height = 270;
    o.hud = true;
    Renderer r(o);
    test::expectGolden("liver_sag", r.render(ms.snap), {8, 0.02});
}

}  // namespace
}  // namespace cutsim
