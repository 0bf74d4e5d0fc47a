// An on-screen window (GLFW) with an OpenGL 3.3 core context and an ImGui context fed by its
// mouse and keyboard, for the live view. A Renderer made with RenderTarget::CurrentContext draws
// into it; the window's own ImGui context draws the control panel on top.
#pragma once

#include "image.hpp"

#include <stdexcept>
#include <string>
#include <vector>

struct GLFWwindow;
struct ImGuiContext;

namespace cutsim::render {

// No display server to open a window on (DISPLAY unset or unreachable, no GLX).
struct NoDisplayError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

class Window {
public:
    // Opens a window of width x height pixels with a 3.3 core context current on this thread and
    // ImGui on it. vsync = false: swap without waiting (headless runs). Throws NoDisplayError
    // when there is no display, std::runtime_error for other failures.
    Window(const std::string& title, int width, int height, bool vsync = true);
    ~Window();
    Window(const Window&) = delete;
    Window& operator=(const Window&) = delete;

    bool shouldClose() const;
    void close();  // shouldClose() is true from now on
    // Polls events and starts the window's ImGui frame; inputs ImGui wants are not reported below.
    void beginFrame();
    void endFrame();  // draws the ImGui frame into the back buffer
    void swap();
    int framebufferWidth() const;
    int framebufferHeight() const;
    Image readBackBuffer() const;  // RGBA, top row first; call after endFrame, before swap

    // Keys pressed since the last call (GLFW key codes), not counting those ImGui took.
    std::vector<int> takeKeys();
    ImGuiContext* ui() const { return ui_; }

private:
    static void onKey(GLFWwindow* w, int key, int scancode, int action, int mods);
    GLFWwindow* window_ = nullptr;
    ImGuiContext* ui_ = nullptr;
    std::vector<int> keys_;
};

}  // namespace cutsim::render
