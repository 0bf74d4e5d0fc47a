// Draws a RenderSnapshot offscreen (EGL, OpenGL 3.3 core, 4x MSAA) with an ImGui HUD and reads
// the frame back. One Renderer owns its GL context; use it from one thread.
#pragma once

#include "image.hpp"
#include "snapshot/snapshot.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <string>

namespace cutsim::render {

class EglContext;

struct RenderOptions {
    int width = 1280;            // frame size [px]
    int height = 720;
    int samples = 4;             // MSAA samples (clamped to what GL offers; 1 = none)
    bool lighting = true;        // false: flat colours exactly as the map gives them (pixel tests)
    bool wireframe = true;       // draw RenderSnapshot::edges when there are any
    bool xray = true;            // draw critical elements through the surface
    bool floor = true;           // floor grid under the surface, for depth cues
    bool legend = true;          // colour bar with ticks when the snapshot has a scalar
    bool hud = false;            // ImGui window with the HUD values
    std::array<std::uint8_t, 3> background{38, 41, 46};       // clear colour
    std::array<std::uint8_t, 3> surfaceColour{222, 184, 166}; // surface without a scalar
    std::array<std::uint8_t, 3> cutColour{196, 60, 84};       // faces made by a cut
    std::array<std::uint8_t, 3> criticalColour{255, 30, 30};  // critical elements
    std::array<std::uint8_t, 3> toolColour{176, 184, 200};
};

// Legend bar rectangle in pixels, top-left origin (x0, y0 inclusive; x1, y1 exclusive).
struct PixelRect {
    float x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

class Renderer {
public:
    // Creates the GL context, framebuffers, shaders and ImGui. Throws std::runtime_error.
    explicit Renderer(const RenderOptions& opts = {});
    ~Renderer();
    Renderer(const Renderer&) = delete;
    Renderer& operator=(const Renderer&) = delete;

    // Draws one frame into the multisampled framebuffer and resolves it.
    void draw(const RenderSnapshot& snap);
    // The last frame, RGBA, top row first.
    Image read() const;
    // draw + read.
    Image render(const RenderSnapshot& snap) {
        draw(snap);
        return read();
    }

    // Toggles may change between frames; width, height and samples are fixed at construction.
    RenderOptions& options() { return opts_; }
    const RenderOptions& options() const { return opts_; }
    int width() const { return opts_.width; }
    int height() const { return opts_.height; }
    int samples() const { return samples_; }       // MSAA samples in use
    const EglContext& context() const { return *ctx_; }
    PixelRect legendRect() const;                  // where the legend bar is drawn

private:
    struct Gl;
    void drawHudAndLegend(const RenderSnapshot& snap);
    RenderOptions opts_;
    int samples_ = 1;
    std::unique_ptr<EglContext> ctx_;
    std::unique_ptr<Gl> gl_;
    bool hudShown_ = false; // ImGui hides a new window on its first frame
};

} // namespace cutsim::render
