#include "renderer.hpp"

#include "colormap.hpp"
#include "egl_context.hpp"
#include "geometry.hpp"
#include "gl_private.hpp"

#include <imgui.h>
#include <backends/imgui_impl_opengl3.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace cutsim::render {
namespace {

using Mat4f = Eigen::Matrix4f;
using Vec3f = Eigen::Vector3f;
using Vec4f = Eigen::Vector4f;
using Vec3d = Eigen::Vector3d;

constexpr float kSegmentHalfWidth = 0.5f;  // smoothed segments' half width [px]

Vec3f rgb(const std::array<std::uint8_t, 3>& c) { return Vec3f(c[0] / 255.0f, c[1] / 255.0f, c[2] / 255.0f); }

Mat4f lookAt(const Vec3d& eye, const Vec3d& target, const Vec3d& up) {
    Vec3d f = (target - eye).normalized();
    Vec3d s = f.cross(up).normalized();
    if (!s.allFinite()) s = f.unitOrthogonal();  // up parallel to the view direction
    Vec3d u = s.cross(f);
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    m.block<1, 3>(0, 0) = s.transpose();
    m.block<1, 3>(1, 0) = u.transpose();
    m.block<1, 3>(2, 0) = -f.transpose();
    m(0, 3) = -s.dot(eye);
    m(1, 3) = -u.dot(eye);
    m(2, 3) = f.dot(eye);
    return m.cast<float>();
}

Mat4f perspective(double fovYDeg, double aspect, double zNear, double zFar) {
    const double f = 1.0 / std::tan(0.5 * fovYDeg * M_PI / 180.0);
    Eigen::Matrix4d m = Eigen::Matrix4d::Zero();
    m(0, 0) = f / aspect;
    m(1, 1) = f;
    m(2, 2) = (zFar + zNear) / (zNear - zFar);
    m(2, 3) = 2 * zFar * zNear / (zNear - zFar);
    m(3, 2) = -1;
    return m.cast<float>();
}

}  // namespace

Renderer::Renderer(const RenderOptions& opts, RenderTarget target)
    : opts_(opts), ctx_(target == RenderTarget::Offscreen ? std::make_unique<EglContext>() : nullptr),
      gl_(std::make_unique<Gl>()) {
    if (opts_.width <= 0 || opts_.height <= 0)
        throw std::runtime_error("render size must be positive, got " + std::to_string(opts_.width) + "x" +
                                 std::to_string(opts_.height));
    const auto* name = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
    if (!name) throw std::runtime_error("no current OpenGL context to render with");
    glRenderer_ = name;
    for (auto [e, out] : {std::pair{GLenum(GL_VENDOR), &glVendor_}, std::pair{GLenum(GL_VERSION), &glVersion_}})
        if (const auto* v = reinterpret_cast<const char*>(glGetString(e))) *out = v;
    Gl& g = *gl_;
    GLint maxSamples = 1;
    glGetIntegerv(GL_MAX_SAMPLES, &maxSamples);
    samples_ = std::clamp(opts_.samples, 1, std::max(1, static_cast<int>(maxSamples)));
    GLint extensions = 0;
    glGetIntegerv(GL_NUM_EXTENSIONS, &extensions);
    for (GLint i = 0; i < extensions; ++i)
        if (const auto* e = reinterpret_cast<const char*>(glGetStringi(GL_EXTENSIONS, static_cast<GLuint>(i))))
            g.packInvert = g.packInvert || std::string(e) == "GL_MESA_pack_invert";
    glGenFramebuffers(1, &g.msFbo);
    glGenRenderbuffers(1, &g.msColour);
    glGenRenderbuffers(1, &g.msDepth);
    glGenFramebuffers(1, &g.outFbo);
    glGenRenderbuffers(1, &g.outColour);
    glGenRenderbuffers(1, &g.outDepth);
    allocateTargets();

    g.makeLineProgram();
    glGenVertexArrays(1, &g.vao);

    // ImGui with its own context per renderer; no window system: the display size is ours.
    g.imgui = ImGui::CreateContext();
    ImGui::SetCurrentContext(g.imgui);
    ImGuiIO& io = ImGui::GetIO();
    io.IniFilename = nullptr;  // no imgui.ini next to the run
    io.LogFilename = nullptr;
    io.DisplaySize = ImVec2(static_cast<float>(opts_.width), static_cast<float>(opts_.height));
    ImGui::StyleColorsDark();
    if (!ImGui_ImplOpenGL3_Init("#version 330 core"))
        throw std::runtime_error("ImGui OpenGL3 backend failed to initialise");
}

void Renderer::allocateTargets() {
    // MSAA: multisampled colour and depth, resolved into the read-back buffer. One sample: the
    // read-back buffer gets a depth buffer and is drawn into directly.
    Gl& g = *gl_;
    auto storage = [&](GLuint rb, int samples, GLenum format) {
        glBindRenderbuffer(GL_RENDERBUFFER, rb);
        if (samples > 1)
            glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples, format, opts_.width, opts_.height);
        else
            glRenderbufferStorage(GL_RENDERBUFFER, format, opts_.width, opts_.height);
    };
    auto complete = [](GLuint fbo, const char* what) {
        glBindFramebuffer(GL_FRAMEBUFFER, fbo);
        if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
            throw std::runtime_error(std::string(what) + " framebuffer incomplete");
    };
    if (samples_ > 1) {
        storage(g.msColour, samples_, GL_RGBA8);
        storage(g.msDepth, samples_, GL_DEPTH_COMPONENT24);
        glBindFramebuffer(GL_FRAMEBUFFER, g.msFbo);
        glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, g.msColour);
        glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, g.msDepth);
        complete(g.msFbo, "multisampled");
    }
    storage(g.outColour, 1, GL_RGBA8);
    glBindFramebuffer(GL_FRAMEBUFFER, g.outFbo);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, g.outColour);
    if (samples_ == 1) storage(g.outDepth, 1, GL_DEPTH_COMPONENT24);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, samples_ == 1 ? g.outDepth : 0);
    complete(g.outFbo, "read-back");
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

void Renderer::resize(int width, int height) {
    if (width <= 0 || height <= 0 || (width == opts_.width && height == opts_.height)) return;
    makeCurrent();
    opts_.width = width;
    opts_.height = height;
    allocateTargets();
}

void Renderer::makeCurrent() const {
    if (ctx_) ctx_->makeCurrent();
}

void Renderer::present(unsigned fbo) const {
    makeCurrent();
    glBindFramebuffer(GL_READ_FRAMEBUFFER, gl_->outFbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, fbo);
    glBlitFramebuffer(0, 0, opts_.width, opts_.height, 0, 0, opts_.width, opts_.height, GL_COLOR_BUFFER_BIT,
                      GL_NEAREST);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

Renderer::~Renderer() {
    makeCurrent();
    Gl& g = *gl_;
    ImGui::SetCurrentContext(g.imgui);
    ImGui_ImplOpenGL3_Shutdown();
    ImGui::DestroyContext(g.imgui);
    if (!g.vbos.empty()) glDeleteBuffers(static_cast<GLsizei>(g.vbos.size()), g.vbos.data());
    glDeleteVertexArrays(1, &g.vao);
    for (const auto& p : g.meshProgs)
        if (p.id) glDeleteProgram(p.id);
    glDeleteProgram(g.lineProg);
    glDeleteFramebuffers(1, &g.msFbo);
    glDeleteFramebuffers(1, &g.outFbo);
    glDeleteFramebuffers(1, &g.still.fbo);
    GLuint rbs[] = {g.msColour, g.msDepth, g.outColour, g.outDepth, g.still.colour};
    glDeleteRenderbuffers(5, rbs);
}

// Scene bounds (surface, critical tets and tools) and a camera whose near and far planes hug the
// scene and the floor around it.
Renderer::View Renderer::viewOf(const RenderSnapshot& snap) const {
    Eigen::AlignedBox3d box;
    for (int v = 0; v < snap.vertices(); ++v) box.extend(snap.positions.col(v));
    for (int v = 0; v < snap.criticalTets.cols(); ++v) box.extend(snap.criticalTets.col(v));
    for (const auto& t : snap.tools) {
        box.extend(t.position + Vec3d::Constant(t.size.norm() * 1.8));
        box.extend(t.position - Vec3d::Constant(t.size.norm() * 1.8));
    }
    if (box.isEmpty()) box.extend(snap.camera.target);
    View v;
    v.centre = box.center();
    v.radius = std::max(0.5 * box.diagonal().norm(), 1e-6);
    v.up = snap.camera.up.normalized();
    const double dist = (snap.camera.eye - v.centre).norm();
    double zFar = dist + 3.0 * v.radius;
    if (snap.floor.fixed) {
        // A fixed floor may reach beyond this frame's scene: keep its corners in front of the far plane.
        const Floor& fl = snap.floor;
        const double reach = std::sqrt(2.0) * fl.halfSize + std::abs(fl.height - fl.centre.dot(fl.normal.normalized()));
        zFar = std::max(zFar, (snap.camera.eye - fl.centre).norm() + reach);
    }
    const double zNear = std::max(dist - 3.0 * v.radius, zFar * 1e-3);
    v.view = lookAt(snap.camera.eye, snap.camera.target, v.up);
    v.proj = perspective(snap.camera.fovY, double(opts_.width) / opts_.height, zNear, zFar);
    v.zNear = static_cast<float>(zNear);
    v.zFar = static_cast<float>(zFar);
    v.bg = rgb(opts_.background);
    return v;
}

void Renderer::drawSurface(const RenderSnapshot& snap, const View& v) {
    Gl& g = *gl_;
    const int n = snap.vertices();
    const bool useMap = snap.scalar.size() == n && n > 0;
    Gl::MeshState& ms = g.ms;
    {
        auto table = colorMapTable(snap.diverging ? ColorMapKind::Diverging : ColorMapKind::Sequential);
        ms.map.fill(0);
        for (size_t i = 0; i < table.size() && i < 16; ++i) {
            ms.map[3 * i] = table[i].r / 255.0f;
            ms.map[3 * i + 1] = table[i].g / 255.0f;
            ms.map[3 * i + 2] = table[i].b / 255.0f;
        }
        ms.mapN = static_cast<int>(std::min<size_t>(table.size(), 16));
    }
    ms.min = static_cast<float>(snap.scalarMin);
    ms.max = static_cast<float>(snap.scalarMax);
    ms.useMap = useMap;
    ms.colour = rgb(opts_.surfaceColour);
    ms.cutColour = rgb(opts_.cutColour);
    ms.lit = opts_.lighting;
    ms.alpha = 1.0f;

    g.topo.update(snap);
    surfaceVertices(snap, g.topo, useMap, g.verts);
    // Pushed back a little so wireframe lines on it win the depth test.
    glEnable(GL_POLYGON_OFFSET_FILL);
    glPolygonOffset(1.0f, 1.0f);
    g.drawMesh(g.verts);
    glDisable(GL_POLYGON_OFFSET_FILL);
    if (smoothEdges()) drawSilhouette(v, &g.topo.half);
}

bool Renderer::smoothEdges() const { return opts_.smoothEdges && samples_ == 1; }

// The silhouette of the soup in Gl::verts as smoothed segments, with the mesh program's uniforms
// as they are.
void Renderer::drawSilhouette(const View& v, const std::vector<std::pair<std::uint64_t, int>>* half) {
    Gl& g = *gl_;
    const Eigen::Matrix3f r = v.view.topLeftCorner<3, 3>();
    const Vec3f eye = -(r.transpose() * v.view.topRightCorner<3, 1>());
    g.silhouette.clear();
    if (half)
        silhouetteLines(g.verts, *half, eye, g.silhouette);
    else
        silhouetteLines(g.verts, g.ids, eye, g.halfEdges, g.silhouette);
    smoothQuads(v);
    drawQuads();
}

// The segments in Gl::silhouette as quads in Gl::quads for drawQuads.
void Renderer::smoothQuads(const View& v) {
    Gl& g = *gl_;
    const Eigen::Matrix4f pv = v.proj * v.view;
    g.quads.clear();
    segmentQuads(g.silhouette, pv, 0.5f * static_cast<float>(opts_.width), 0.5f * static_cast<float>(opts_.height),
                 kSegmentHalfWidth, g.quads);
}

// Gl::quads blended over what is drawn, 1 px wide with a 1 px ramp, writing no depth, in one
// colour.
void Renderer::drawQuads(const Vec4f& colour) {
    Gl& g = *gl_;
    g.ms.useMap = false;
    g.ms.lit = false;
    g.ms.colour = colour.head<3>();
    g.ms.alpha = colour.w();
    drawQuads();
    g.ms.lit = opts_.lighting;
    g.ms.alpha = 1.0f;
}

// The same with the mesh program's other uniforms as they are.
void Renderer::drawQuads() {
    Gl& g = *gl_;
    g.ms.edgeHalf = kSegmentHalfWidth;
    blendOver();
    glDepthMask(GL_FALSE);
    g.drawMesh(g.quads);
    glDepthMask(GL_TRUE);
    glDisable(GL_BLEND);
    g.ms.edgeHalf = 0.0f;
}

void Renderer::setSegments(const std::vector<float>& xyz) {
    Gl& g = *gl_;
    g.silhouette.clear();
    for (size_t i = 0; i + 2 < xyz.size(); i += 3)
        g.silhouette.push_back({{xyz[i], xyz[i + 1], xyz[i + 2]}, {0, 0, 1}, 0, 0});
}

// Lines of one colour (xyz pairs): smoothed segments when they are in use, else GL lines.
void Renderer::drawColourLines(const std::vector<float>& xyz, const Vec4f& colour, const View& v) {
    Gl& g = *gl_;
    if (!smoothEdges()) {
        glUseProgram(g.lineProg);
        glUniformMatrix4fv(g.lView, 1, GL_FALSE, v.view.data());
        glUniformMatrix4fv(g.lProj, 1, GL_FALSE, v.proj.data());
        glUniform4f(g.lColour, colour.x(), colour.y(), colour.z(), colour.w());
        g.drawLines(xyz);
        return;
    }
    setSegments(xyz);
    smoothQuads(v);
    drawQuads(colour);
}

void Renderer::drawTools(const RenderSnapshot& snap, const View& v) {
    if (snap.tools.empty()) return;
    Gl& g = *gl_;
    g.verts.clear();
    for (const auto& t : snap.tools) toolTriangles(t, g.verts);
    const Vec3f tc = rgb(opts_.toolColour);
    g.ms.useMap = false;
    g.ms.colour = tc;
    g.drawMesh(g.verts);
    if (smoothEdges()) {
        g.ids.clear();  // corners at one position are one vertex
        drawSilhouette(v);
    }
}

// Wireframe.
void Renderer::drawLines(const RenderSnapshot& snap, const View& v) {
    Gl& g = *gl_;
    if (opts_.wireframe && snap.edges.cols() >= 2) {
        g.lines.resize(3 * static_cast<size_t>(snap.edges.cols()));
        Eigen::Map<Eigen::Matrix3Xf>(g.lines.data(), 3, snap.edges.cols()) = snap.edges.cast<float>();
        drawColourLines(g.lines, Vec4f(0.08f, 0.08f, 0.1f, 1.0f), v);
    }
}

// The floor grid's segments (xyz pairs) into `lines`; false when there is no floor.
bool Renderer::floorLines(const RenderSnapshot& snap, const View& v, std::vector<float>& lines) const {
    const int n = snap.vertices();
    const Vec3d& up = v.up;
    if (!opts_.floor || (!snap.floor.fixed && n == 0)) return false;
    // Grid in a plane normal to up: where the scene puts it, or just under this frame's lowest
    // surface point.
    const Floor& fl = snap.floor;
    const Vec3d nrm = fl.fixed ? Vec3d(fl.normal.normalized()) : up;
    const Vec3d e1 = nrm.unitOrthogonal(), e2 = nrm.cross(e1);
    double step = 0, half = 0;
    Vec3d origin;
    if (fl.fixed) {
        step = fl.spacing;
        half = fl.halfSize;
        origin = fl.centre + (fl.height - fl.centre.dot(nrm)) * nrm;
    } else {
        double low = snap.positions.col(0).dot(up);
        for (int i = 1; i < n; ++i) low = std::min(low, snap.positions.col(i).dot(up));
        origin = v.centre + (low - 0.02 * v.radius - v.centre.dot(up)) * up;
        step = niceGridStep(v.radius / 4);
        half = std::ceil(2.0 * v.radius / step) * step;
    }
    lines.clear();
    for (double s = -half; s <= half + 0.5 * step; s += step)
        for (int axis = 0; axis < 2; ++axis) {
            const Vec3d a = axis ? e1 : e2, b = axis ? e2 : e1;
            for (double end : {-half, half}) {
                Vec3f p = (origin + s * a + end * b).cast<float>();
                lines.insert(lines.end(), {p.x(), p.y(), p.z()});
            }
        }
    return true;
}

// The clear colour and the floor grid, drawn first so the smoothed edges in front blend over it.
// The floor's smoothed segments write no depth, so where no corner of them comes near the near or
// far plane (which follow the scene each frame) the two give the same colours for the same camera
// whatever the planes: for a camera still two frames running they are drawn once into Gl::still
// and each frame starts from a copy of it and a cleared depth.
void Renderer::drawBackground(const RenderSnapshot& snap, const View& v) {
    Gl& g = *gl_;
    const Vec4f floorColour(v.bg.x() + 0.12f, v.bg.y() + 0.12f, v.bg.z() + 0.12f, 1.0f);
    const bool floor = floorLines(snap, v, g.lines);
    glClearColor(v.bg.x(), v.bg.y(), v.bg.z(), 1.0f);
    glClearDepth(1.0);
    Gl::Still& st = g.still;
    if (!floor || !smoothEdges() || !insideDepthRange(g.lines, v)) {
        st.last.clear();
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        if (floor) drawColourLines(g.lines, floorColour, v);
        return;
    }
    setSegments(g.lines);
    smoothQuads(v);
    // What the layer's pixels depend on: the quads, the camera (not its depth row), the colours.
    st.key.assign(reinterpret_cast<const float*>(g.quads.data()),
                  reinterpret_cast<const float*>(g.quads.data() + g.quads.size()));
    st.key.insert(st.key.end(), v.view.data(), v.view.data() + 16);
    for (int r : {0, 1, 3})
        for (int c = 0; c < 4; ++c) st.key.push_back(v.proj(r, c));
    st.key.insert(st.key.end(), {v.bg.x(), v.bg.y(), v.bg.z(), float(opts_.width), float(opts_.height)});
    const GLuint target = g.outFbo;
    auto copy = [&] {
        glBindFramebuffer(GL_READ_FRAMEBUFFER, st.fbo);
        glBindFramebuffer(GL_DRAW_FRAMEBUFFER, target);
        glBlitFramebuffer(0, 0, opts_.width, opts_.height, 0, 0, opts_.width, opts_.height, GL_COLOR_BUFFER_BIT,
                          GL_NEAREST);
        glBindFramebuffer(GL_FRAMEBUFFER, target);
        glClear(GL_DEPTH_BUFFER_BIT);
    };
    if (st.valid && st.key == st.drawn) return copy();
    const bool still = st.key == st.last;
    std::swap(st.last, st.key);
    if (!still) {
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        drawQuads(floorColour);
        return;
    }
    if (!st.fbo || st.width != opts_.width || st.height != opts_.height) {
        if (!st.fbo) {
            glGenFramebuffers(1, &st.fbo);
            glGenRenderbuffers(1, &st.colour);
        }
        glBindRenderbuffer(GL_RENDERBUFFER, st.colour);
        glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, opts_.width, opts_.height);
        glBindFramebuffer(GL_FRAMEBUFFER, st.fbo);
        glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, st.colour);
        st.width = opts_.width;
        st.height = opts_.height;
    }
    glBindFramebuffer(GL_FRAMEBUFFER, st.fbo);
    glClear(GL_COLOR_BUFFER_BIT);
    drawQuads(floorColour);
    st.drawn = st.last;
    st.valid = true;
    copy();
}

// True when every point of `xyz` lies between the near and far planes, clear of both.
bool Renderer::insideDepthRange(const std::vector<float>& xyz, const View& v) const {
    constexpr float kMargin = 1e-3f;
    const Eigen::RowVector4f depth = -v.view.row(2);
    for (size_t i = 0; i + 2 < xyz.size(); i += 3) {
        const float d = depth.dot(Eigen::Vector4f(xyz[i], xyz[i + 1], xyz[i + 2], 1.0f));
        if (!(d > v.zNear * (1 + kMargin) && d < v.zFar * (1 - kMargin))) return false;
    }
    return true;
}

// Tets in Gl::critTris / critLines through the surface (x-ray): no depth test, blended faces and
// edges.
void Renderer::drawXray(const Vec3f& face, float faceAlpha, const Vec4f& edge, const View& v) {
    Gl& g = *gl_;
    glDisable(GL_DEPTH_TEST);
    blendOver();
    g.ms.useMap = false;
    g.ms.lit = false;
    g.ms.colour = face;
    g.ms.alpha = faceAlpha;
    g.drawMesh(g.critTris);
    drawColourLines(g.critLines, edge, v);
    glDisable(GL_BLEND);
    glEnable(GL_DEPTH_TEST);
}

// The critical elements, edges halfway to white so they read on faces of their own colour.
void Renderer::drawCriticalXray(const View& v) {
    const Vec3f cc = rgb(opts_.criticalColour);
    drawXray(cc, 0.35f, Vec4f(0.5f * (cc.x() + 1), 0.5f * (cc.y() + 1), 0.5f * (cc.z() + 1), 0.9f), v);
}

// The elements a cut made critical and the step policy answered: outlines over a faint fill, so
// they read as resolved next to the filled critical ones.
void Renderer::drawAnsweredXray(const RenderSnapshot& snap, const View& v) {
    Gl& g = *gl_;
    g.critTris.clear();
    g.critLines.clear();
    tetGeometry(snap.answeredTets, g.critTris, g.critLines);
    const Vec3f ac = rgb(opts_.answeredColour);
    drawXray(ac, 0.12f, Vec4f(ac.x(), ac.y(), ac.z(), 0.95f), v);
}

void Renderer::draw(const RenderSnapshot& snap) {
    makeCurrent();
    Gl& g = *gl_;
    const View v = viewOf(snap);
    g.nextVbo = 0;
    g.ms.view = v.view;
    g.ms.proj = v.proj;
    glBindFramebuffer(GL_FRAMEBUFFER, samples_ > 1 ? g.msFbo : g.outFbo);
    glViewport(0, 0, opts_.width, opts_.height);
    glDepthMask(GL_TRUE);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LEQUAL);
    glDisable(GL_CULL_FACE);
    glDisable(GL_BLEND);
    glDisable(GL_SCISSOR_TEST);
    glBindVertexArray(g.vao);

    // The surface, the tools, the critical elements where visible, the lines, then the critical
    // elements through the surface.
    drawBackground(snap, v);
    drawSurface(snap, v);
    drawTools(snap, v);
    const bool xray = opts_.xray && snap.criticalTets.cols() >= 4;
    if (xray) {
        g.critTris.clear();
        g.critLines.clear();
        tetGeometry(snap.criticalTets, g.critTris, g.critLines);
        const Vec3f cc = rgb(opts_.criticalColour);
        g.ms.useMap = false;
        g.ms.colour = cc;
        g.drawMesh(g.critTris);
    }
    drawLines(snap, v);
    if (xray) drawCriticalXray(v);
    if (opts_.xray && snap.answeredTets.cols() >= 4) drawAnsweredXray(snap, v);
    glBindVertexArray(0);

    // 2D: legend and HUD (ImGui draws into the bound framebuffer).
    drawHudAndLegend(snap);

    if (samples_ > 1) {  // resolve the samples into the read-back target
        glBindFramebuffer(GL_READ_FRAMEBUFFER, g.msFbo);
        glBindFramebuffer(GL_DRAW_FRAMEBUFFER, g.outFbo);
        glBlitFramebuffer(0, 0, opts_.width, opts_.height, 0, 0, opts_.width, opts_.height, GL_COLOR_BUFFER_BIT,
                          GL_NEAREST);
    }
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glFlush();  // llvmpipe rasterises from here on, while the caller does other work until read
}

void Renderer::warmUp() {
    RenderSnapshot s;
    s.positions.resize(3, 4);
    s.positions << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
    s.triangles.resize(3, 4);
    s.triangles << 0, 0, 0, 1, 2, 1, 3, 2, 1, 3, 2, 3;
    s.cutFace = {0, 0, 0, 1};
    s.scalar.resize(4);
    s.scalar << 0, 1, 2, 3;
    s.scalarMax = 3;
    s.scalarName = "warm-up";
    s.edges = s.positions.leftCols(2);
    s.criticalTets = s.positions;
    s.answeredTets = s.positions;
    ToolShape tool;
    tool.position = Vec3d(0.3, 0.3, 1.2);
    tool.size = Vec3d::Constant(0.1);
    s.tools.push_back(tool);
    s.camera = frameBox(Vec3d::Constant(-0.2), Vec3d::Constant(1.4));
    s.hud.lines = {"warm-up"};
    s.hud.forcePlot = {0.0f, 1.0f};
    s.hud.answeredElements = 1;
    Image img;
    draw(s);
    read(img);
}

Image Renderer::read() const {
    Image img;
    read(img);
    return img;
}

void Renderer::read(Image& img) const {
    makeCurrent();
    img.width = opts_.width;
    img.height = opts_.height;
    img.rgba.resize(4 * static_cast<size_t>(img.width) * static_cast<size_t>(img.height));
    glBindFramebuffer(GL_READ_FRAMEBUFFER, gl_->outFbo);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    // GL's first row is the bottom one: Mesa reads the rows top first as it copies them
    // (MESA_pack_invert); elsewhere they are flipped in place (no second frame-sized buffer).
    if (gl_->packInvert) glPixelStorei(GL_PACK_INVERT_MESA, GL_TRUE);
    glReadPixels(0, 0, img.width, img.height, GL_RGBA, GL_UNSIGNED_BYTE, img.rgba.data());
    glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    if (gl_->packInvert) {
        glPixelStorei(GL_PACK_INVERT_MESA, GL_FALSE);
        return;
    }
    const size_t row = 4 * static_cast<size_t>(img.width);
    for (int y = 0; y < img.height / 2; ++y)
        std::swap_ranges(img.rgba.begin() + static_cast<std::ptrdiff_t>(row * static_cast<size_t>(y)),
                         img.rgba.begin() + static_cast<std::ptrdiff_t>(row * static_cast<size_t>(y + 1)),
                         img.rgba.begin() + static_cast<std::ptrdiff_t>(row * static_cast<size_t>(img.height - 1 - y)));
}

}  // namespace cutsim::render
