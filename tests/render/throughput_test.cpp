// Throughput of the capture path, reported rather than asserted (timings are per machine):
//   ./test_render --gtest_also_run_disabled_tests --gtest_filter='*Throughput*'
#include "egl_context.hpp"
#include "png_writer.hpp"
#include "renderer.hpp"
#include "snapshot/snapshot.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>

namespace cutsim {
namespace {

// A bumpy sphere of about 20k triangles with a scalar, like a mid-size organ surface.
RenderSnapshot bumpySphere(int nu, int nv) {
    RenderSnapshot s;
    s.positions.resize(3, nu * (nv + 1));
    s.scalar.resize(nu * (nv + 1));
    for (int j = 0; j <= nv; ++j)
        for (int i = 0; i < nu; ++i) {
            const double th = M_PI * j / nv, ph = 2 * M_PI * i / nu;
            const double r = 0.05 * (1 + 0.08 * std::sin(5 * ph) * std::sin(4 * th));
            s.positions.col(j * nu + i) << r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph),
                r * std::cos(th);
            s.scalar[j * nu + i] = std::cos(th);
        }
    s.triangles.resize(3, 2 * nu * nv);
    int f = 0;
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            const int a = j * nu + i, b = j * nu + (i + 1) % nu, c = a + nu, d = b + nu;
            s.triangles.col(f++) << a, c, d;
            s.triangles.col(f++) << a, d, b;
        }
    s.scalarMin = -1;
    s.scalarMax = 1;
    s.scalarName = "z";
    s.camera = frameBox(Eigen::Vector3d::Constant(-0.05), Eigen::Vector3d::Constant(0.05));
    return s;
}

TEST(RenderThroughput, DISABLED_Frames1280x720) {
    const RenderSnapshot s = bumpySphere(100, 100);
    render::RenderOptions o;  // 1280 x 720, 4x MSAA
    o.hud = true;
    render::Renderer r(o);
    r.render(s);  // warm up: shader compile, first ImGui frame
    using clock = std::chrono::steady_clock;
    const int n = 30;
    auto t0 = clock::now();
    render::Image img;
    for (int i = 0; i < n; ++i) img = r.render(s);
    const double renderFps = n / std::chrono::duration<double>(clock::now() - t0).count();

    const std::string dir = ::testing::TempDir();
    t0 = clock::now();
    const int np = 10;
    for (int i = 0; i < np; ++i) render::writePng(dir + "/throughput.png", img);
    const double pngFps = np / std::chrono::duration<double>(clock::now() - t0).count();
    std::printf("renderer %s, %d triangles at %dx%d, %d samples\n", r.context().renderer().c_str(), s.faces(), o.width,
                o.height, r.samples());
    std::printf("render+readback %.1f frames/s, PNG encode+write %.1f frames/s\n", renderFps, pngFps);
}

}  // namespace
}  // namespace cutsim
