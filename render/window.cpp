#include "window.hpp"

#include "gl.hpp"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <imgui.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>

#include <algorithm>
#include <cstdlib>

namespace cutsim::render {
namespace {

std::string g_glfwError;  // last GLFW error, for the exception message

void onGlfwError(int, const char* msg) { g_glfwError = msg ? msg : "unknown GLFW error"; }

// Why there is no display, in words a user can act on.
std::string noDisplayMessage() {
    const char* display = std::getenv("DISPLAY");
    std::string what = display && *display ? "cannot open a window on display '" + std::string(display) + "'"
                                           : "no display to open a window on (DISPLAY is not set)";
    return what + " [GLFW: " + g_glfwError +
           "]; run it under a display server, e.g. `xvfb-run -a cutsim view ...`, or use `cutsim run` "
           "for offscreen frames";
}

}  // namespace

Window::Window(const std::string& title, int width, int height, bool vsync) {
    glfwSetErrorCallback(onGlfwError);
    g_glfwError.clear();
    if (!glfwInit()) throw NoDisplayError(noDisplayMessage());
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_SAMPLES, 0);  // the Renderer multisamples offscreen
    window_ = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
    if (!window_) {
        const std::string msg = g_glfwError;
        glfwTerminate();
        // Both "no GLX on this display" and "no 3.3 core context" end here.
        throw NoDisplayError("cannot create an OpenGL 3.3 core window [GLFW: " + msg +
                             "]; `cutsim run` renders offscreen without a display");
    }
    glfwMakeContextCurrent(window_);
    glfwSwapInterval(vsync ? 1 : 0);
    glfwSetWindowUserPointer(window_, this);
    // Installed before ImGui's callbacks, which chain to it.
    glfwSetKeyCallback(window_, onKey);

    ImGuiContext* previous = ImGui::GetCurrentContext();
    ui_ = ImGui::CreateContext();
    ImGui::SetCurrentContext(ui_);
    ImGuiIO& io = ImGui::GetIO();
    io.IniFilename = nullptr;
    io.LogFilename = nullptr;
    ImGui::StyleColorsDark();
    if (!ImGui_ImplGlfw_InitForOpenGL(window_, true) || !ImGui_ImplOpenGL3_Init("#version 330 core")) {
        ImGui::DestroyContext(ui_);
        glfwDestroyWindow(window_);
        glfwTerminate();
        throw std::runtime_error("ImGui GLFW/OpenGL3 backends failed to initialise");
    }
    if (previous) ImGui::SetCurrentContext(previous);
}

Window::~Window() {
    glfwMakeContextCurrent(window_);
    ImGui::SetCurrentContext(ui_);
    ImGui_ImplOpenGL3_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext(ui_);
    glfwDestroyWindow(window_);
    glfwTerminate();
}

void Window::onKey(GLFWwindow* w, int key, int, int action, int) {
    if (action != GLFW_PRESS) return;
    auto* self = static_cast<Window*>(glfwGetWindowUserPointer(w));
    if (self) self->keys_.push_back(key);
}

bool Window::shouldClose() const { return glfwWindowShouldClose(window_); }
void Window::close() { glfwSetWindowShouldClose(window_, GLFW_TRUE); }

void Window::beginFrame() {
    ImGui::SetCurrentContext(ui_);  // the backend's callbacks feed the current context
    glfwPollEvents();
    ImGui_ImplOpenGL3_NewFrame();
    ImGui_ImplGlfw_NewFrame();
    ImGui::NewFrame();
}

void Window::endFrame() {
    ImGui::SetCurrentContext(ui_);  // a Renderer switches to its own context while drawing
    ImGui::Render();
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glViewport(0, 0, framebufferWidth(), framebufferHeight());
    ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
}

void Window::swap() { glfwSwapBuffers(window_); }

int Window::framebufferWidth() const {
    int w = 0, h = 0;
    glfwGetFramebufferSize(window_, &w, &h);
    return w;
}

int Window::framebufferHeight() const {
    int w = 0, h = 0;
    glfwGetFramebufferSize(window_, &w, &h);
    return h;
}

Image Window::readBackBuffer() const {
    Image img;
    img.width = framebufferWidth();
    img.height = framebufferHeight();
    const size_t row = 4 * static_cast<size_t>(img.width);
    std::vector<std::uint8_t> raw(row * static_cast<size_t>(img.height));
    glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    glReadBuffer(GL_BACK);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, img.width, img.height, GL_RGBA, GL_UNSIGNED_BYTE, raw.data());
    img.rgba.resize(raw.size());
    // GL's first row is the bottom one.
    for (int y = 0; y < img.height; ++y)
        std::copy_n(raw.data() + row * static_cast<size_t>(img.height - 1 - y), row,
                    img.rgba.data() + row * static_cast<size_t>(y));
    // The window's alpha channel is not part of the picture.
    for (size_t p = 3; p < img.rgba.size(); p += 4) img.rgba[p] = 255;
    return img;
}

std::vector<int> Window::takeKeys() {
    std::vector<int> k;
    k.swap(keys_);
    ImGui::SetCurrentContext(ui_);
    if (ImGui::GetIO().WantCaptureKeyboard) k.clear();  // typing into a widget
    return k;
}

}  // namespace cutsim::render
