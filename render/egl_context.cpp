#include "egl_context.hpp"

#include "gl.hpp"

#define EGL_NO_X11 1
#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <cstring>
#include <stdexcept>

namespace cutsim::render {
namespace {

bool hasExtension(const char* list, const char* name) {
    if (!list) return false;
    const size_t n = std::strlen(name);
    for (const char* p = list; (p = std::strstr(p, name)); p += n)
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
    return false;
}

// Tries the display paths in order; returns an initialised display or EGL_NO_DISPLAY.
EGLDisplay openDisplay(std::string& platform) {
    const char* clientExt = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    auto getPlatformDisplay =
        reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
    auto tryInit = [](EGLDisplay d) {
        if (d == EGL_NO_DISPLAY) return false;
        EGLint major = 0, minor = 0;
        return eglInitialize(d, &major, &minor) == EGL_TRUE;
    };
    // 1. Mesa's surfaceless platform: no display server, no device node needed.
    if (getPlatformDisplay && hasExtension(clientExt, "EGL_MESA_platform_surfaceless")) {
        EGLDisplay d = getPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
        if (tryInit(d)) {
            platform = "surfaceless";
            return d;
        }
    }
    // 2. The first EGL device (headless GPU drivers).
    auto queryDevices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    if (getPlatformDisplay && queryDevices && hasExtension(clientExt, "EGL_EXT_platform_device")) {
        EGLDeviceEXT devices[8];
        EGLint n = 0;
        if (queryDevices(8, devices, &n) && n > 0) {
            EGLDisplay d = getPlatformDisplay(EGL_PLATFORM_DEVICE_EXT, devices[0], nullptr);
            if (tryInit(d)) {
                platform = "device";
                return d;
            }
        }
    }
    // 3. Whatever the default display is.
    EGLDisplay d = eglGetDisplay(EGL_DEFAULT_DISPLAY);
    if (tryInit(d)) {
        platform = "default";
        return d;
    }
    return EGL_NO_DISPLAY;
}

}  // namespace

EglContext::EglContext() {
    EGLDisplay dpy = openDisplay(platform_);
    if (dpy == EGL_NO_DISPLAY)
        throw std::runtime_error("no EGL display: tried EGL_PLATFORM_SURFACELESS_MESA, EGL devices and "
                                 "EGL_DEFAULT_DISPLAY (install Mesa's EGL, e.g. libegl-mesa0)");
    display_ = dpy;
    if (!eglBindAPI(EGL_OPENGL_API)) {
        eglTerminate(dpy);
        throw std::runtime_error("EGL display has no desktop OpenGL API (eglBindAPI(EGL_OPENGL_API) failed)");
    }
    // No config and no surface: everything renders into framebuffer objects.
    const char* dpyExt = eglQueryString(dpy, EGL_EXTENSIONS);
    EGLConfig config = EGL_NO_CONFIG_KHR;
    if (!hasExtension(dpyExt, "EGL_KHR_no_config_context")) {
        const EGLint attrs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
        EGLint n = 0;
        eglChooseConfig(dpy, attrs, &config, 1, &n);
        if (n < 1) config = EGL_NO_CONFIG_KHR;
    }
    const EGLint ctxAttrs[] = {
        EGL_CONTEXT_MAJOR_VERSION,           3,       EGL_CONTEXT_MINOR_VERSION, 3, EGL_CONTEXT_OPENGL_PROFILE_MASK,
        EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    EGLContext ctx = eglCreateContext(dpy, config, EGL_NO_CONTEXT, ctxAttrs);
    if (ctx == EGL_NO_CONTEXT) {
        eglTerminate(dpy);
        throw std::runtime_error("no OpenGL 3.3 core context on the EGL display (" + platform_ + ")");
    }
    context_ = ctx;
    if (!eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, ctx)) {
        eglDestroyContext(dpy, ctx);
        eglTerminate(dpy);
        throw std::runtime_error("cannot make the OpenGL context current without a surface "
                                 "(EGL_KHR_surfaceless_context missing)");
    }
    auto str = [](GLenum e) {
        const auto* s = reinterpret_cast<const char*>(glGetString(e));
        return std::string(s ? s : "");
    };
    renderer_ = str(GL_RENDERER);
    version_ = str(GL_VERSION);
    GLint major = 0, minor = 0;
    glGetIntegerv(GL_MAJOR_VERSION, &major);
    glGetIntegerv(GL_MINOR_VERSION, &minor);
    if (major * 10 + minor < 33) {
        eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        eglDestroyContext(dpy, ctx);
        eglTerminate(dpy);
        throw std::runtime_error("OpenGL 3.3 needed, the context has " + version_);
    }
}

EglContext::~EglContext() {
    auto dpy = static_cast<EGLDisplay>(display_);
    eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(dpy, static_cast<EGLContext>(context_));
    // Not eglTerminate: the display is shared by every context of the process (EGL displays are
    // per process), and terminating it would break another live renderer.
}

void EglContext::makeCurrent() {
    eglMakeCurrent(static_cast<EGLDisplay>(display_), EGL_NO_SURFACE, EGL_NO_SURFACE,
                   static_cast<EGLContext>(context_));
}

}  // namespace cutsim::render
