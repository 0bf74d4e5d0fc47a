// An offscreen OpenGL 3.3 core context on EGL without a window or display server.
#pragma once

#include <string>

namespace cutsim::render {

class EglContext {
public:
    // Opens a display (surfaceless Mesa, then a device, then the default display) and makes a
    // 3.3 core context current on this thread. Throws std::runtime_error naming what is missing.
    EglContext();
    ~EglContext();
    EglContext(const EglContext&) = delete;
    EglContext& operator=(const EglContext&) = delete;

    void makeCurrent();
    const std::string& platform() const { return platform_; }  // which display path worked
    const std::string& renderer() const { return renderer_; }  // GL_RENDERER, e.g. "llvmpipe ..."
    const std::string& version() const { return version_; }    // GL_VERSION

private:
    void* display_ = nullptr;  // EGLDisplay
    void* context_ = nullptr;  // EGLContext
    std::string platform_, renderer_, version_;
};

}  // namespace cutsim::render
