// Draws a RenderSnapshot (OpenGL 3.3 core, 4x MSAA) with an ImGui HUD and reads the frame back.
// Offscreen, a Renderer owns its EGL context; in a window it uses the window's context and copies
// each frame to the window's default framebuffer (present). Use it from one thread.
#pragma once

#include "image.hpp"
#include "snapshot/snapshot.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace cutsim::render {

class EglContext;

struct RenderOptions {
    int width = 1280;  // frame size [px]
    int height = 720;
    int samples = 1;          // MSAA samples (clamped to what GL offers); on llvmpipe 4 cost ~3x a frame
    bool smoothEdges = true;  // with one sample: anti-aliased lines and silhouettes (GL_LINE_SMOOTH),
                              // the cheap alternative to MSAA on a CPU rasteriser
    bool lighting = true;     // false: flat colours exactly as the map gives them (pixel tests)
    bool wireframe = true;    // draw RenderSnapshot::edges when there are any
    bool xray = true;         // draw critical elements through the surface
    bool floor = true;        // floor grid under the surface, for depth cues
    bool legend = true;       // colour bar with ticks when the snapshot has a scalar
    bool hud = false;         // ImGui window with the HUD values
    std::array<std::uint8_t, 3> background{38, 41, 46};        // clear colour
    std::array<std::uint8_t, 3> surfaceColour{222, 184, 166};  // surface without a scalar
    std::array<std::uint8_t, 3> cutColour{196, 60, 84};        // faces made by a cut
    std::array<std::uint8_t, 3> criticalColour{0, 230, 255};   // critical elements: cyan, a colour no map, cut
                                                               // face, tool or surface uses
    std::array<std::uint8_t, 3> toolColour{176, 184, 200};
    std::array<std::uint8_t, 3> answeredColour{255, 70, 255};  // elements a cut made critical and the step
                                                               // policy answered: outlined in magenta
};

// Legend bar rectangle in pixels, top-left origin (x0, y0 inclusive; x1, y1 exclusive).
struct PixelRect {
    float x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

// Where a Renderer gets its GL context.
enum class RenderTarget : std::uint8_t {
    Offscreen,       // its own EGL context, no display needed
    CurrentContext,  // the context current on this thread (e.g. a GLFW window's); it must stay
                     // current whenever the Renderer is used
};

class Renderer {
public:
    // Creates (or takes) the GL context, framebuffers, shaders and ImGui. Throws std::runtime_error.
    explicit Renderer(const RenderOptions& opts = {}, RenderTarget target = RenderTarget::Offscreen);
    ~Renderer();
    Renderer(const Renderer&) = delete;
    Renderer& operator=(const Renderer&) = delete;

    // Draws one frame into the multisampled framebuffer and resolves it.
    void draw(const RenderSnapshot& snap);
    // The last frame, RGBA, top row first.
    Image read() const;
    // The same into `img`, reusing its buffer (no allocation when it already has the size).
    void read(Image& img) const;
    // Draws and reads a small frame with everything the options show (a surface with a colour
    // map and a cut face, a tool, critical and answered elements, the floor, HUD and legend), so
    // that the shaders and the rasteriser's code for them are compiled before the first real
    // frame. The last frame is then that one.
    void warmUp();
    // draw + read.
    Image render(const RenderSnapshot& snap) {
        draw(snap);
        return read();
    }

    // Copies the last frame into framebuffer `fbo` (0: a window's back buffer) at the same size.
    void present(unsigned fbo = 0) const;
    // New frame size (a resized window); the next draw uses it.
    void resize(int width, int height);

    // Toggles may change between frames; width and height change only through resize.
    RenderOptions& options() { return opts_; }
    const RenderOptions& options() const { return opts_; }
    int width() const { return opts_.width; }
    int height() const { return opts_.height; }
    int samples() const { return samples_; }                       // MSAA samples in use
    const EglContext& context() const { return *ctx_; }            // Offscreen only
    const std::string& glRenderer() const { return glRenderer_; }  // GL_RENDERER
    const std::string& glVendor() const { return glVendor_; }      // GL_VENDOR
    const std::string& glVersion() const { return glVersion_; }    // GL_VERSION
    PixelRect legendRect() const;                                  // where the legend bar is drawn

private:
    struct Gl;
    struct View;
    View viewOf(const RenderSnapshot& snap) const;
    void drawSurface(const RenderSnapshot& snap, const View& v);
    void drawTools(const RenderSnapshot& snap, const View& v);
    // Of the soup in Gl::verts: its edges sorted (half), or found from Gl::ids.
    void drawSilhouette(const View& v, const std::vector<std::pair<std::uint64_t, int>>* half = nullptr);
    void setSegments(const std::vector<float>& xyz);  // xyz pairs into Gl::silhouette
    void smoothQuads(const View& v);                  // Gl::silhouette into Gl::quads
    void drawQuads();
    void drawQuads(const Eigen::Vector4f& colour);
    void drawColourLines(const std::vector<float>& xyz, const Eigen::Vector4f& colour, const View& v);
    bool smoothEdges() const;  // smoothed lines and silhouettes in use
    void drawLines(const RenderSnapshot& snap, const View& v);
    bool floorLines(const RenderSnapshot& snap, const View& v, std::vector<float>& lines) const;
    void drawBackground(const RenderSnapshot& snap, const View& v);
    bool insideDepthRange(const std::vector<float>& xyz, const View& v) const;
    void drawCriticalXray(const View& v);
    void drawXray(const Eigen::Vector3f& face, float faceAlpha, const Eigen::Vector4f& edge, const View& v);
    void drawAnsweredXray(const RenderSnapshot& snap, const View& v);
    void drawHudAndLegend(const RenderSnapshot& snap);
    void makeCurrent() const;
    void allocateTargets();  // framebuffers at opts_ size
    RenderOptions opts_;
    std::string glRenderer_, glVendor_, glVersion_;
    int samples_ = 1;
    std::unique_ptr<EglContext> ctx_;
    std::unique_ptr<Gl> gl_;
};

}  // namespace cutsim::render
