// `cutsim render MESH`: draw a tet mesh offscreen (EGL) and write a PNG.
#include "cmd_render.hpp"

#include "commands.hpp"

#include "mesh/io.hpp"
#include "snapshot/snapshot.hpp"

#ifdef CUTSIM_HAVE_RENDER
#include "egl_context.hpp"
#include "png_writer.hpp"
#include "renderer.hpp"
#endif

#include <CLI/CLI.hpp>

#include <filesystem>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>

namespace cutsim::app {
namespace {

struct RenderArgs {
    std::string mesh;
    std::string out = "render.png";
    double scale = 1.0;
    int width = 1280;
    int height = 720;
    bool wireframe = false;
    int samples = 4;  // a still: MSAA costs nothing that matters
    std::string field = "volume";
    bool hud = false;
};

int runRender(const RenderArgs& a) {
    try {
#ifndef CUTSIM_HAVE_RENDER
        (void)a;
        throw std::runtime_error("this cutsim was built without the renderer (-DCUTSIM_RENDER=OFF)");
#else
        ReadOptions ro;
        ro.scale = a.scale;
        const TetMesh m = readTetMesh(a.mesh, ro);
        if (m.elements() == 0) throw InputError(a.mesh, 0, "no tetrahedra to render");

        MeshSnapshotOptions so;
        so.wireframe = a.wireframe;
        Eigen::VectorXd volume;
        if (a.field == "volume") {
            volume.resize(m.elements());
            for (int e = 0; e < m.elements(); ++e) volume[e] = tetSignedVolume(m, e);
            so.elementValues = &volume;
            so.name = "volume";
            so.unit = "m^3";
        }
        MeshSnapshot ms = snapshotFromTetMesh(m, so);
        ms.snap.hud.simulated = false;
        ms.snap.hud.lines = {std::filesystem::path(a.mesh).filename().string(),
                             std::to_string(m.nodes()) + " nodes, " + std::to_string(m.elements()) + " tets, " +
                                 std::to_string(ms.snap.faces()) + " surface triangles"};

        render::RenderOptions opts;
        opts.width = a.width;
        opts.height = a.height;
        opts.hud = a.hud;
        opts.wireframe = a.wireframe;
        opts.samples = a.samples;
        render::Renderer r(opts);
        render::writePng(a.out, r.render(ms.snap));
        std::cout << "written: " << a.out << " (" << a.width << "x" << a.height << ", " << ms.snap.faces()
                  << " triangles, " << r.context().renderer() << ")\n";
        return 0;
#endif
    } catch (const std::exception& e) {
        std::cerr << "error: " << e.what() << "\n";
        return 2;
    }
}

}  // namespace

void addRenderCommand(CLI::App& app) {
    auto args = std::make_shared<RenderArgs>();
    CLI::App* cmd = app.add_subcommand("render", "Draw a tet mesh offscreen (EGL, no display needed) to a PNG");
    cmd->add_option("MESH", args->mesh, "Tet mesh: .msh (Gmsh 1, 2.2, 4.1), .node/.ele (TetGen), .mesh (MEDIT), .vtu")
        ->required();
    cmd->add_option("--scale", args->scale, "Multiply every coordinate by S (e.g. 0.01 for cm to m)")
        ->check(CLI::PositiveNumber);
    cmd->add_option("--out", args->out, "PNG to write (written to FILE.tmp, then renamed)")->capture_default_str();
    cmd->add_option("--width", args->width, "Image width [px]")->check(CLI::Range(16, 8192))->capture_default_str();
    cmd->add_option("--height", args->height, "Image height [px]")->check(CLI::Range(16, 8192))->capture_default_str();
    cmd->add_flag("--wireframe", args->wireframe, "Draw every tet edge");
    cmd->add_option("--samples", args->samples, "MSAA samples (1: smoothed lines and silhouettes instead)")
        ->check(CLI::Range(1, 16))
        ->capture_default_str();
    cmd->add_option("--field", args->field, "Colour by: volume (per-element volume [m^3]) or none")
        ->check(CLI::IsMember({"volume", "none"}))
        ->capture_default_str();
    cmd->add_flag("--hud", args->hud, "Draw the HUD panel (mesh name and size)");
    cmd->callback([args] { setExitCode(runRender(*args)); });
}

}  // namespace cutsim::app
