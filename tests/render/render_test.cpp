// Renderer: exact pixels where they can be computed, golden images for whole scenes.
#include "colormap.hpp"
#include "egl_context.hpp"
#include "golden.hpp"
#include "renderer.hpp"
#include "snapshot/scene_snapshot.hpp"
#include "snapshot/snapshot.hpp"
#include "sim/simulation.hpp"
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

// A scene's frames keep one colour map range and one floor: 19 um of noise is near the bottom of
// the displacement map, not full yellow, and a piece falling 5 cm moves neither the range nor the floor.
TEST(Render, SceneFramesKeepTheirRangeAndFloor) {
    SceneDef sc = loadScene(test::source("assets/scenes/bar_sag.json"));  // 1 x 0.1 x 0.1 m, displacement map
    const Simulation sim(sc);
    SceneSnapshot scene(sc, sim.model(), sim.analyzer().estimates().r1r, sim.dt());
    State s = sim.state();
    s.x = sim.model().X + 19e-6 * Eigen::Matrix3Xd::Random(3, sim.model().nodes());
    const RenderSnapshot noisy = scene.update(sim.model(), s, FrameInfo{});
    // 5 % of the 1.01 m diagonal, rounded up to 0.1 m
    EXPECT_DOUBLE_EQ(noisy.scalarMin, 0);
    EXPECT_DOUBLE_EQ(noisy.scalarMax, 0.1);
    EXPECT_LT(noisy.scalar.maxCoeff() / noisy.scalarMax, 0.001);
    EXPECT_TRUE(noisy.floor.fixed);
    EXPECT_DOUBLE_EQ(noisy.floor.height, sim.model().X.row(2).minCoeff());  // lowest rest point along +z (gravity -z)
    const Floor before = noisy.floor;
    s.x.row(2).array() -= 0.05;
    const RenderSnapshot fallen = scene.update(sim.model(), s, FrameInfo{});
    EXPECT_DOUBLE_EQ(fallen.scalarMax, 0.1);
    EXPECT_DOUBLE_EQ(fallen.floor.height, before.height);
    EXPECT_TRUE(fallen.floor.centre.isApprox(before.centre));
    // A range the scene sets, and a floor height it sets.
    sc = loadScene(test::source("assets/scenes/bar_sag.json"),
                   {"capture.range=[0, 0.02]", "capture.floor_height=-0.2", "capture.colormap=\"stress\""});
    SceneSnapshot set(sc, sim.model(), sim.analyzer().estimates().r1r, sim.dt());
    const RenderSnapshot a = set.update(sim.model(), s, FrameInfo{});
    EXPECT_DOUBLE_EQ(a.scalarMin, 0);
    EXPECT_DOUBLE_EQ(a.scalarMax, 0.02);
    EXPECT_DOUBLE_EQ(a.floor.height, -0.2);
}

// Critical elements are drawn in a colour far from every other feature's: both colour maps, the
// cut faces, the plain surface and the tools.
TEST(Render, CriticalColourIsUsedByNothingElse) {
    const RenderOptions o;
    auto dist = [](std::array<int, 3> a, std::array<int, 3> b) {
        return std::sqrt(
            double((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2])));
    };
    auto arr = [](std::array<std::uint8_t, 3> c) { return std::array<int, 3>{c[0], c[1], c[2]}; };
    const auto crit = arr(o.criticalColour);
    for (auto other : {o.cutColour, o.surfaceColour, o.toolColour, o.background, o.answeredColour})
        EXPECT_GT(dist(crit, arr(other)), 120);
    for (ColorMapKind k : {ColorMapKind::Sequential, ColorMapKind::Diverging})
        for (int i = 0; i <= 100; ++i) {
            const auto c = render::colorMapLookup(k, i / 100.0);
            EXPECT_GT(dist(crit, {int(c[0] * 255), int(c[1] * 255), int(c[2] * 255)}), 90) << i;
        }
}

MeshSnapshot boxWithCritical();

// Pixels of a frame that are neither the background nor `colour` (exactly).
int mixedPixels(const Image& img, const std::array<std::uint8_t, 3>& bg, const std::array<std::uint8_t, 3>& colour) {
    int mixed = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const auto p = img.pixel(x, y);
            const bool isBg = p[0] == bg[0] && p[1] == bg[1] && p[2] == bg[2];
            const bool isColour = p[0] == colour[0] && p[1] == colour[1] && p[2] == colour[2];
            mixed += !isBg && !isColour;
        }
    return mixed;
}

// With one sample, the smoothed silhouette blends an unlit box into the background along its
// outline (about its perimeter in pixels); without it, every pixel is one or the other.
TEST(Render, SmoothedSilhouetteBlendsTheOutline) {
    RenderOptions o = goldenOptions();
    o.lighting = false;
    o.floor = false;
    o.legend = false;
    o.samples = 1;
    const RenderSnapshot snap = snapshotFromTetMesh(scenebox()).snap;
    o.smoothEdges = false;
    EXPECT_EQ(mixedPixels(Renderer(o).render(snap), o.background, o.surfaceColour), 0);
    o.smoothEdges = true;
    const int mixed = mixedPixels(Renderer(o).render(snap), o.background, o.surfaceColour);
    EXPECT_GT(mixed, 150);  // the box's outline is ~400 px long at 320x180
    EXPECT_LT(mixed, 2000);
}

// Blended overlays (x-ray, smoothed edges) leave the frame opaque: a PNG with alpha under 255
// shows lighter wherever a viewer composites it over white.
TEST(Render, FramesAreOpaque) {
    for (int samples : {1, 4}) {
        RenderOptions o = goldenOptions();
        o.samples = samples;
        const MeshSnapshot ms = boxWithCritical();
        const Image img = Renderer(o).render(ms.snap);
        int translucent = 0;
        for (size_t i = 3; i < img.rgba.size(); i += 4) translucent += img.rgba[i] != 255;
        EXPECT_EQ(translucent, 0) << samples << " samples";
    }
}

// ---- golden scenes ----

// The box with its bump field and a few critical elements.
MeshSnapshot boxWithCritical() {
    const TetMesh m = scenebox();
    const Eigen::VectorXd f = bumpField(m);
    MeshSnapshotOptions so;
    so.elementValues = &f;
    so.name = "bump";
    so.critical = someCritical(m);
    return snapshotFromTetMesh(m, so);
}

TEST(RenderGolden, BoxWithField) {
    const MeshSnapshot ms = boxWithCritical();
    ASSERT_GT(ms.snap.criticalTets.cols(), 0);
    Renderer r(goldenOptions());
    test::expectGolden("box_field", r.render(ms.snap), {8, 0.01});
}

// Elements a cut made critical and the step policy answered: magenta outlines through the surface,
// beside the critical ones (cyan), each with its swatch and count under the colour bar.
TEST(RenderGolden, AnsweredElementsBesideCriticalOnes) {
    MeshSnapshot ms = boxWithCritical();
    const TetMesh m = scenebox();
    // answered: the critical set moved 1 cm along x
    Eigen::Matrix3Xd moved = ms.snap.criticalTets;
    moved.row(0).array() -= 0.01;
    ms.snap.answeredTets = moved;
    ms.snap.hud.answeredElements = static_cast<int>(moved.cols() / 4);
    RenderOptions o = goldenOptions();
    o.lighting = false;
    const Image img = Renderer(o).render(ms.snap);
    int magenta = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const auto p = img.pixel(x, y);
            magenta += p[0] == o.answeredColour[0] && p[1] == o.answeredColour[1] && p[2] == o.answeredColour[2];
        }
    EXPECT_GT(magenta, 20);  // the legend's swatch at least
    test::expectGolden("answered", img, {5, 0.001});
}

// Critical elements in x-ray with their legend: the swatch under the colour bar is exactly the
// critical colour (nothing else on screen uses it), and the frame matches its golden at the
// renderdiff tolerance.
TEST(RenderGolden, CriticalElementsAndTheirLegend) {
    MeshSnapshot ms = boxWithCritical();
    ms.snap.hud.criticalStep = 1.25e-5;
    RenderOptions o = goldenOptions();
    o.lighting = false;
    Renderer r(o);
    const Image img = r.render(ms.snap);
    const render::PixelRect bar = r.legendRect();
    int swatch = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const auto p = img.pixel(x, y);
            const bool exact =
                p[0] == o.criticalColour[0] && p[1] == o.criticalColour[1] && p[2] == o.criticalColour[2];
            if (y > bar.y1 + 4) swatch += exact;  // below the bar: the swatch only
        }
    EXPECT_GE(swatch, 50) << "the swatch under the colour bar";
    test::expectGolden("critical", img, {5, 0.001});
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

// A sphere tool seen along its axis, pole first, over a quad of tissue: unlit, the pixel
// through the pole must be the tool's colour (a hole there shows the tissue), for both poles.
TEST(RenderGolden, SphereToolHasNoHoleAtItsPoles) {
    RenderOptions o = goldenOptions();
    o.lighting = false;
    o.floor = false;
    o.legend = false;
    Renderer r(o);
    for (double flip : {0.0, M_PI}) {  // the upper pole towards the camera, then the lower one
        RenderSnapshot s = screenQuad(0, 0, 1, false);
        s.scalar.resize(0);
        s.positions.row(2).setConstant(-0.05);  // tissue behind the tool
        ToolShape t;
        t.kind = ToolShape::Kind::Sphere;
        t.size = Eigen::Vector3d::Constant(0.02);
        t.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(flip, Eigen::Vector3d::UnitX()));
        s.tools = {t};
        s.camera.eye = {0, 0, 0.2};
        const Image img = r.render(s);
        const auto p = img.pixel(kGoldenW / 2, kGoldenH / 2);
        for (int c = 0; c < 3; ++c) EXPECT_EQ(p[c], o.toolColour[c]) << "pole " << flip << " channel " << c;
        if (flip == 0) test::expectGolden("sphere_pole", img, {5, 0.001});
    }
}

// The box of scenebox() moved down by drop [m], with a floor fixed at its rest height.
RenderSnapshot fallingBox(double drop, bool fixedFloor) {
    const TetMesh m = scenebox();
    Eigen::Matrix3Xd x = m.X;
    x.row(2).array() -= drop;
    RenderSnapshot s = snapshotFromTetMesh(m, x).snap;
    s.camera = snapshotFromTetMesh(m).snap.camera;  // the camera does not follow the fall
    s.floor.fixed = fixedFloor;
    s.floor.normal = s.camera.up;
    s.floor.height = 0;
    s.floor.centre = {0.02, 0.01, 0};
    s.floor.spacing = 0.01;
    s.floor.halfSize = 0.05;
    return s;
}

// Pixels that differ from the background by more than the grid's contrast: the object's.
std::vector<bool> objectMask(const Image& img, const RenderOptions& o) {
    std::vector<bool> m(size_t(img.width) * size_t(img.height));
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const auto p = img.pixel(x, y);
            int d = 0;
            for (int c = 0; c < 3; ++c) d = std::max(d, std::abs(int(p[c]) - int(o.background[c])));
            m[size_t(y) * size_t(img.width) + size_t(x)] = d > 0;
        }
    return m;
}

// Pixels, at least 2 px away from the object in both frames, that differ between frames a and b.
int gridChanges(const Image& a, const Image& b, const std::vector<bool>& ma, const std::vector<bool>& mb) {
    int changed = 0;
    for (int y = 2; y < a.height - 2; ++y)
        for (int x = 2; x < a.width - 2; ++x) {
            bool near = false;
            for (int dy = -2; dy <= 2; ++dy)
                for (int dx = -2; dx <= 2; ++dx) {
                    const size_t i = size_t(y + dy) * size_t(a.width) + size_t(x + dx);
                    near = near || ma[i] || mb[i];
                }
            if (near) continue;
            const auto p = a.pixel(x, y), q = b.pixel(x, y);
            changed += p[0] != q[0] || p[1] != q[1] || p[2] != q[2];
        }
    return changed;
}

// A falling piece must not move the floor: away from the object the frames before and after the
// fall are the same pixels; the per-frame floor (not fixed) moves with the lowest point.
TEST(RenderGolden, FloorStaysWhereTheScenePutsIt) {
    RenderOptions o = goldenOptions();
    o.legend = false;
    Renderer r(o);
    RenderOptions noFloor = o;
    noFloor.floor = false;
    Renderer bare(noFloor);
    const std::vector<bool> m0 = objectMask(bare.render(fallingBox(0, true)), o),
                            m1 = objectMask(bare.render(fallingBox(0.015, true)), o);
    const Image before = r.render(fallingBox(0, true)), after = r.render(fallingBox(0.015, true));
    EXPECT_EQ(gridChanges(before, after, m0, m1), 0);
    EXPECT_GT(gridChanges(r.render(fallingBox(0, false)), r.render(fallingBox(0.015, false)), m0, m1), 100)
        << "the test must see a floor that drops";
    test::expectGolden("floor_fixed", after, {5, 0.001});
}

// With a still camera the background and floor are drawn once and each frame starts from a copy of
// them: every frame is the one a renderer draws whole, also while the falling box moves the near
// and far planes, after the camera moves away and when it comes back.
TEST(Render, StillCameraFramesAreTheFramesDrawnWhole) {
    const RenderOptions o = goldenOptions();
    Renderer r(o), whole(o);
    std::vector<RenderSnapshot> fall;
    for (double drop : {0.0, 0.004, 0.008, 0.012}) fall.push_back(fallingBox(drop, true));
    RenderSnapshot moved = fall[1], away = fall[0];
    moved.camera.eye += Eigen::Vector3d(0.01, 0, 0);
    away.camera.eye += Eigen::Vector3d(0, 0.02, 0);
    int frame = 0;
    for (const RenderSnapshot* s : {&fall[0], &fall[1], &fall[2], &moved, &moved, &fall[3], &fall[3], &fall[0]}) {
        const Image a = r.render(*s);
        whole.render(away);  // a camera that moves every frame: `whole` draws each frame whole
        const Image b = whole.render(*s);
        EXPECT_TRUE(a.rgba == b.rgba) << "frame " << frame;
        ++frame;
    }
    RenderOptions noFloor = o;
    noFloor.floor = false;
    Renderer bare(noFloor);
    const std::vector<bool> m0 = objectMask(bare.render(fall[0]), o), m1 = objectMask(bare.render(away), o);
    EXPECT_GT(gridChanges(whole.render(fall[0]), whole.render(away), m0, m1), 100) << "the floor must show";
}

// `cutsim render --hud` draws a still mesh: no time, step or count lines ("dt used 0").
TEST(RenderGolden, HudOfAStillMesh) {
    MeshSnapshot ms = snapshotFromTetMesh(scenebox());
    ms.snap.hud.simulated = false;
    ms.snap.hud.lines = {"box.msh", "45 nodes, 192 tets"};
    RenderOptions o = goldenOptions();
    o.hud = true;
    Renderer r(o);
    test::expectGolden("hud_still", r.render(ms.snap), {5, 0.001});
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

// A line that appears in the HUD (a cut's answered count) is inside the panel in the frame it
// appears: the frame equals one a fresh renderer draws (ImGui sizes an auto-resized window from
// its previous frame's content unless laid out first).
TEST(Render, HudLineAddedThisFrameIsInsideThePanel) {
    MeshSnapshot ms = snapshotFromTetMesh(scenebox());
    HudValues& h = ms.snap.hud;
    h.simTime = 0.125;
    h.dtUsed = 2.5e-5;
    h.dtCertified = 2.4e-5;
    RenderOptions o = goldenOptions();
    o.hud = true;
    Renderer before(o);
    before.render(ms.snap);
    h.answeredElements = 5;
    h.lines = {"scene: golden", "a longer line that widens the panel"};
    const Image grown = before.render(ms.snap);
    Renderer fresh(o);
    const Image direct = fresh.render(ms.snap);
    ASSERT_EQ(grown.rgba.size(), direct.rgba.size());
    EXPECT_TRUE(grown.rgba == direct.rgba);
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

// liver_cuts.json's smooth visual surface (4384 triangles) on the 596-tet liver after its first two
// cuts at 0.2 and 0.4 s, sagging at 0.5 s: smooth shading, the time-step map of the tets it rides,
// the cut faces split in it.
TEST(RenderGolden, LiverVisualSurfaceCut) {
    const SceneDef sc = loadScene(test::source("assets/scenes/liver_cuts.json"));
    ASSERT_FALSE(sc.visual.empty());
    SimulationOptions so;
    so.threads = 1;
    so.renderSurface = true;
    Simulation sim(sc, so);
    ASSERT_EQ(sim.advance(0.5), RunStatus::Running);
    ASSERT_EQ(sim.scriptedCutsDone(), 2u);
    SceneSnapshot scene(sc, sim.model(), sim.analyzer().estimates().r1r, sim.dt(), sim.surface());
    FrameInfo fi;
    fi.time = sim.state().time;
    RenderSnapshot& snap = scene.update(sim.model(), sim.state(), fi);
    EXPECT_GT(snap.vertices(), 2194);
    Renderer r(goldenOptions());
    test::expectGolden("liver_visual_cut", r.render(snap), {8, 0.01});
}

}  // namespace
}  // namespace cutsim
