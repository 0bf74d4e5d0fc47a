#include "renderer.hpp"

#include "colormap.hpp"
#include "egl_context.hpp"
#include "geometry.hpp"
#include "gl.hpp"

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

// ---- shaders ----
// Surface: per-vertex scalar mapped per fragment (so a colour map step stays sharp), two
// directional lights fixed to the camera (key and fill, Phong), lit from both sides because cut
// and open surfaces show their back.
constexpr const char* kMeshVs = R"(#version 330 core
layout(location = 0) in vec3 aPos;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in float aScalar;
layout(location = 3) in float aCut;
layout(location = 4) in float aEdge;
layout(location = 5) in vec2 aOffset;  // smoothed segments: offset in normalised device coordinates
uniform mat4 uView;
uniform mat4 uProj;
out vec3 vNormal;
out vec3 vPosV;
out float vScalar;
out float vCut;
noperspective out float vEdge;
void main() {
    vec4 pv = uView * vec4(aPos, 1.0);
    vPosV = pv.xyz;
    vNormal = mat3(uView) * aNormal;
    vScalar = aScalar;
    vCut = aCut;
    vEdge = aEdge;
    gl_Position = uProj * pv;
    gl_Position.xy += aOffset * gl_Position.w;
}
)";

// Compiled in variants (MAP, LIT, EDGE: 0 or 1, see Renderer::Gl::program): llvmpipe runs both
// sides of a branch for every fragment, so a flat segment must not pay for lighting and the map.
constexpr const char* kMeshFs = R"(
in vec3 vNormal;
in vec3 vPosV;
in float vScalar;
in float vCut;
noperspective in float vEdge;  // smoothed segments: distance from the centre line [px]
uniform float uEdgeHalf;       // their half width [px] (EDGE)
uniform vec3 uMap[16];
uniform int uMapN;
uniform float uMin;
uniform float uMax;
uniform vec3 uColour;
uniform vec3 uCutColour;
uniform float uAlpha;
out vec4 fragColour;
vec3 colourMap(float s) {
    float t = clamp((s - uMin) / max(uMax - uMin, 1e-30), 0.0, 1.0);
    float x = t * float(uMapN - 1);
    int i = min(int(floor(x)), uMapN - 2);
    return mix(uMap[i], uMap[i + 1], x - float(i));
}
void main() {
#if MAP
    vec3 base = colourMap(vScalar);
#else
    vec3 base = uColour;
#endif
    if (vCut > 0.5) base = uCutColour;
#if EDGE
    float alpha = uAlpha * clamp(uEdgeHalf + 0.5 - abs(vEdge), 0.0, 1.0);
#else
    float alpha = uAlpha;
#endif
#if LIT
    vec3 n = normalize(vNormal);
    vec3 v = normalize(-vPosV);
    if (dot(n, v) < 0.0) n = -n;
    vec3 key = normalize(vec3(0.45, 0.65, 0.6));
    vec3 fill = normalize(vec3(-0.6, -0.25, 0.5));
    float diffuse = 0.7 * max(dot(n, key), 0.0) + 0.3 * max(dot(n, fill), 0.0);
    // Cut faces: a wet, glossier material than the capsule, so a cut reads as fresh tissue.
    bool cut = vCut > 0.5;
    float spec = (cut ? 0.45 : 0.22) * pow(max(dot(reflect(-key, n), v), 0.0), cut ? 60.0 : 32.0);
    fragColour = vec4(base * (0.22 + diffuse) + vec3(spec), alpha);
#else
    fragColour = vec4(base, alpha);
#endif
}
)";

constexpr const char* kLineVs = R"(#version 330 core
layout(location = 0) in vec3 aPos;
uniform mat4 uView;
uniform mat4 uProj;
void main() { gl_Position = uProj * uView * vec4(aPos, 1.0); }
)";

constexpr const char* kLineFs = R"(#version 330 core
uniform vec4 uColour;
out vec4 fragColour;
void main() { fragColour = uColour; }
)";

GLuint compile(GLenum type, const char* src) {
    GLuint s = glCreateShader(type);
    glShaderSource(s, 1, &src, nullptr);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[2048];
        glGetShaderInfoLog(s, sizeof log, nullptr, log);
        glDeleteShader(s);
        throw std::runtime_error(std::string("shader compile failed: ") + log);
    }
    return s;
}

GLuint link(const char* vs, const char* fs) {
    GLuint v = compile(GL_VERTEX_SHADER, vs), f = compile(GL_FRAGMENT_SHADER, fs);
    GLuint p = glCreateProgram();
    glAttachShader(p, v);
    glAttachShader(p, f);
    glLinkProgram(p);
    glDeleteShader(v);
    glDeleteShader(f);
    GLint ok = 0;
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[2048];
        glGetProgramInfoLog(p, sizeof log, nullptr, log);
        glDeleteProgram(p);
        throw std::runtime_error(std::string("shader link failed: ") + log);
    }
    return p;
}

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

// GL objects.
struct Renderer::Gl {
    GLuint msFbo = 0, msColour = 0, msDepth = 0;     // multisampled target (MSAA)
    GLuint outFbo = 0, outColour = 0, outDepth = 0;  // read back; drawn into directly with one sample
    GLuint lineProg = 0;
    GLuint vao = 0;
    // One buffer per draw of a frame, kept between frames: rewriting a buffer a pending draw reads
    // would wait for it, and new storage each draw is page faults.
    std::vector<GLuint> vbos;
    std::vector<GLsizeiptr> vboBytes;
    size_t nextVbo = 0;  // the draw's buffer; 0 at the start of a frame
    ImGuiContext* imgui = nullptr;
    std::vector<MeshVertex> verts;     // reused between frames
    std::vector<MeshVertex> critTris;  // critical elements' faces and edges, this frame
    std::vector<float> critLines;
    std::vector<float> lines;
    std::vector<MeshVertex> silhouette;                    // this frame's silhouette segments
    std::vector<MeshVertex> quads;                         // smoothed segments as triangles
    std::vector<std::pair<std::uint64_t, int>> halfEdges;  // scratch of silhouetteLines
    SurfaceTopology topo;                                  // of the last surface drawn
    std::vector<int> ids;
    // What the next mesh draw uses; drawMesh picks the program variant and sets its uniforms.
    struct MeshState {
        Mat4f view = Mat4f::Identity(), proj = Mat4f::Identity();
        std::array<float, 16 * 3> map{};
        int mapN = 2;
        float min = 0, max = 1;
        bool useMap = false, lit = true;
        Vec3f colour = Vec3f::Ones(), cutColour = Vec3f::Ones();
        float alpha = 1, edgeHalf = 0;  // edgeHalf > 0: smoothed segments
    } ms;
    // The mesh program's variants by (MAP, LIT, EDGE), linked on first use, and their uniforms.
    struct MeshProgram {
        GLuint id = 0;
        GLint view = -1, proj = -1, map = -1, mapN = -1, min = -1, max = -1, colour = -1, cutColour = -1, alpha = -1,
              edgeHalf = -1;
    };
    std::array<MeshProgram, 8> meshProgs;
    GLint lView = -1, lProj = -1, lColour = -1;

    // Binds the mesh program variant for `ms` with its uniforms.
    void useMeshProgram() {
        const bool edge = ms.edgeHalf > 0;
        MeshProgram& p = meshProgs[(ms.useMap ? 1 : 0) + (ms.lit ? 2 : 0) + (edge ? 4 : 0)];
        if (!p.id) {
            const std::string fs = std::string("#version 330 core\n#define MAP ") + (ms.useMap ? "1" : "0") +
                                   "\n#define LIT " + (ms.lit ? "1" : "0") + "\n#define EDGE " + (edge ? "1" : "0") +
                                   kMeshFs;
            p.id = link(kMeshVs, fs.c_str());
            auto loc = [&](const char* n) { return glGetUniformLocation(p.id, n); };
            p.view = loc("uView");
            p.proj = loc("uProj");
            p.map = loc("uMap");
            p.mapN = loc("uMapN");
            p.min = loc("uMin");
            p.max = loc("uMax");
            p.colour = loc("uColour");
            p.cutColour = loc("uCutColour");
            p.alpha = loc("uAlpha");
            p.edgeHalf = loc("uEdgeHalf");
        }
        glUseProgram(p.id);
        glUniformMatrix4fv(p.view, 1, GL_FALSE, ms.view.data());
        glUniformMatrix4fv(p.proj, 1, GL_FALSE, ms.proj.data());
        glUniform3fv(p.map, 16, ms.map.data());  // -1 (unused in the variant): ignored
        glUniform1i(p.mapN, ms.mapN);
        glUniform1f(p.min, ms.min);
        glUniform1f(p.max, ms.max);
        glUniform3f(p.colour, ms.colour.x(), ms.colour.y(), ms.colour.z());
        glUniform3f(p.cutColour, ms.cutColour.x(), ms.cutColour.y(), ms.cutColour.z());
        glUniform1f(p.alpha, ms.alpha);
        glUniform1f(p.edgeHalf, ms.edgeHalf);
    }

    // Binds the next buffer of this frame with `bytes` of data.
    void upload(const void* data, GLsizeiptr bytes) {
        if (nextVbo == vbos.size()) {
            vbos.push_back(0);
            vboBytes.push_back(0);
            glGenBuffers(1, &vbos.back());
        }
        glBindBuffer(GL_ARRAY_BUFFER, vbos[nextVbo]);
        if (vboBytes[nextVbo] < bytes) {
            vboBytes[nextVbo] = bytes + bytes / 2;  // room for a frame with a little more
            glBufferData(GL_ARRAY_BUFFER, vboBytes[nextVbo], nullptr, GL_DYNAMIC_DRAW);
        }
        glBufferSubData(GL_ARRAY_BUFFER, 0, bytes, data);
        ++nextVbo;
    }
    // Uploads and draws interleaved mesh vertices (triangles, or segments with GL_LINES).
    void drawMesh(const std::vector<MeshVertex>& v, GLenum mode = GL_TRIANGLES) {
        if (v.empty()) return;
        useMeshProgram();
        upload(v.data(), static_cast<GLsizeiptr>(v.size() * sizeof(MeshVertex)));
        const GLsizei stride = sizeof(MeshVertex);
        glEnableVertexAttribArray(0);
        glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<void*>(offsetof(MeshVertex, p)));
        glEnableVertexAttribArray(1);
        glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<void*>(offsetof(MeshVertex, n)));
        glEnableVertexAttribArray(2);
        glVertexAttribPointer(2, 1, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<void*>(offsetof(MeshVertex, s)));
        glEnableVertexAttribArray(3);
        glVertexAttribPointer(3, 1, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<void*>(offsetof(MeshVertex, cut)));
        glEnableVertexAttribArray(4);
        glVertexAttribPointer(4, 1, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<void*>(offsetof(MeshVertex, edge)));
        glEnableVertexAttribArray(5);
        glVertexAttribPointer(5, 2, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<void*>(offsetof(MeshVertex, off)));
        glDrawArrays(mode, 0, static_cast<GLsizei>(v.size()));
    }
    // Uploads and draws line segments (xyz pairs).
    void drawLines(const std::vector<float>& l) {
        if (l.empty()) return;
        upload(l.data(), static_cast<GLsizeiptr>(l.size() * sizeof(float)));
        glEnableVertexAttribArray(0);
        glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
        for (GLuint a = 1; a < 6; ++a) glDisableVertexAttribArray(a);
        glDrawArrays(GL_LINES, 0, static_cast<GLsizei>(l.size() / 3));
    }
};

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
    glGenFramebuffers(1, &g.msFbo);
    glGenRenderbuffers(1, &g.msColour);
    glGenRenderbuffers(1, &g.msDepth);
    glGenFramebuffers(1, &g.outFbo);
    glGenRenderbuffers(1, &g.outColour);
    glGenRenderbuffers(1, &g.outDepth);
    allocateTargets();

    g.lineProg = link(kLineVs, kLineFs);
    auto loc = [](GLuint p, const char* n) { return glGetUniformLocation(p, n); };
    g.lView = loc(g.lineProg, "uView");
    g.lProj = loc(g.lineProg, "uProj");
    g.lColour = loc(g.lineProg, "uColour");
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
    GLuint rbs[] = {g.msColour, g.msDepth, g.outColour, g.outDepth};
    glDeleteRenderbuffers(4, rbs);
}

PixelRect Renderer::legendRect() const {
    // Right edge, half the height, room for tick labels on its right.
    const float w = static_cast<float>(opts_.width), h = static_cast<float>(opts_.height);
    const float barW = std::max(8.0f, std::round(0.015f * w));
    const float labelW = 62.0f;
    PixelRect r;
    r.x1 = w - labelW - 10.0f;
    r.x0 = r.x1 - barW;
    r.y0 = std::round(0.25f * h);
    r.y1 = std::round(0.75f * h);
    return r;
}

// The camera and the scene's extent for one frame.
struct Renderer::View {
    Mat4f view, proj;
    Vec3d centre = Vec3d::Zero(), up = Vec3d::UnitZ();
    double radius = 1;
    Vec3f bg = Vec3f::Zero();
};

namespace {

// Alpha blending that leaves the frame opaque: a frame read back with alpha under 1 shows lighter
// wherever a viewer composites the PNG over white.
void blendOver() {
    glEnable(GL_BLEND);
    glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ZERO, GL_ONE);
}

}  // namespace

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
    drawSmoothSegments(v);
}

// The segments in Gl::silhouette blended over what is drawn, 1 px wide with a 1 px ramp, writing no depth; the mesh
// program's other uniforms as they are.
void Renderer::drawSmoothSegments(const View& v) {
    Gl& g = *gl_;
    constexpr float kHalfWidth = 0.5f;
    const Eigen::Matrix4f pv = v.proj * v.view;
    g.quads.clear();
    segmentQuads(g.silhouette, pv, 0.5f * static_cast<float>(opts_.width), 0.5f * static_cast<float>(opts_.height),
                 kHalfWidth, g.quads);
    g.ms.edgeHalf = kHalfWidth;
    blendOver();
    glDepthMask(GL_FALSE);
    g.drawMesh(g.quads);
    glDepthMask(GL_TRUE);
    glDisable(GL_BLEND);
    g.ms.edgeHalf = 0.0f;
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
    g.silhouette.clear();
    for (size_t i = 0; i + 2 < xyz.size(); i += 3)
        g.silhouette.push_back({{xyz[i], xyz[i + 1], xyz[i + 2]}, {0, 0, 1}, 0, 0});
    g.ms.useMap = false;
    g.ms.lit = false;
    g.ms.colour = colour.head<3>();
    g.ms.alpha = colour.w();
    drawSmoothSegments(v);
    g.ms.lit = opts_.lighting;
    g.ms.alpha = 1.0f;
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

// The floor grid, drawn first so the smoothed edges in front blend over it.
void Renderer::drawFloor(const RenderSnapshot& snap, const View& v) {
    Gl& g = *gl_;
    const int n = snap.vertices();
    const Vec3d& up = v.up;
    const Vec3f& bg = v.bg;
    if (opts_.floor && (snap.floor.fixed || n > 0)) {
        // Grid in a plane normal to up: where the scene puts it, or just under this frame's
        // lowest surface point.
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
        g.lines.clear();
        for (double s = -half; s <= half + 0.5 * step; s += step)
            for (int axis = 0; axis < 2; ++axis) {
                const Vec3d a = axis ? e1 : e2, b = axis ? e2 : e1;
                for (double end : {-half, half}) {
                    Vec3f p = (origin + s * a + end * b).cast<float>();
                    g.lines.insert(g.lines.end(), {p.x(), p.y(), p.z()});
                }
            }
        drawColourLines(g.lines, Vec4f(bg.x() + 0.12f, bg.y() + 0.12f, bg.z() + 0.12f, 1.0f), v);
    }
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
    glClearColor(v.bg.x(), v.bg.y(), v.bg.z(), 1.0f);
    glClearDepth(1.0);
    glDepthMask(GL_TRUE);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LEQUAL);
    glDisable(GL_CULL_FACE);
    glDisable(GL_BLEND);
    glDisable(GL_SCISSOR_TEST);
    glBindVertexArray(g.vao);

    // The surface, the tools, the critical elements where visible, the lines, then the critical
    // elements through the surface.
    drawFloor(snap, v);
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

void Renderer::drawHudAndLegend(const RenderSnapshot& snap) {
    Gl& g = *gl_;
    const bool legend = opts_.legend && snap.scalar.size() == snap.vertices() && snap.vertices() > 0;
    const int critical = opts_.xray ? static_cast<int>(snap.criticalTets.cols() / 4) : 0;
    const int answered = opts_.xray ? static_cast<int>(snap.answeredTets.cols() / 4) : 0;
    const bool critLegend = opts_.legend && (critical > 0 || answered > 0);
    if (!legend && !critLegend && !opts_.hud) return;
    ImGui::SetCurrentContext(g.imgui);
    ImGuiIO& io = ImGui::GetIO();
    io.DisplaySize = ImVec2(static_cast<float>(opts_.width), static_cast<float>(opts_.height));
    io.DeltaTime = 1.0f / 30.0f;  // fixed: frames must not depend on wall-clock time

    auto hudWindow = [&] {
        const HudValues& h = snap.hud;
        ImGui::SetNextWindowPos(ImVec2(8, 8));
        ImGui::SetNextWindowBgAlpha(0.6f);
        const ImGuiWindowFlags flags = ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize |
                                       ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoFocusOnAppearing |
                                       ImGuiWindowFlags_NoNav | ImGuiWindowFlags_NoInputs;
        ImGui::Begin("hud", nullptr, flags);
        // A still mesh (cutsim render) has no time, step or counts to show.
        if (h.simulated) {
            ImGui::Text("t        %.4f s", h.simTime);
            ImGui::Text("dt used  %.3e s", h.dtUsed);
            ImGui::Text("dt cert  %.3e s", h.dtCertified);
            if (std::isnan(h.dtExact))
                ImGui::Text("dt exact n/a");
            else
                ImGui::Text("dt exact %.3e s", h.dtExact);
            if (!std::isnan(h.stepsPerSecond)) {  // NaN: not shown (wall-clock rates differ run to run)
                ImGui::Text("steps/s  %.0f", h.stepsPerSecond);
                ImGui::Text("RT x     %.3f", h.realTimeFactor);
            }
            ImGui::Text("critical %d", h.criticalElements);
            if (h.answeredElements > 0) ImGui::Text("answered %d", h.answeredElements);
            ImGui::Text("cuts     %d", h.cuts);
        }
        for (const auto& line : h.lines) ImGui::TextUnformatted(line.c_str());
        if (!h.forcePlot.empty()) {
            float top = 0;
            for (float f : h.forcePlot) top = std::max(top, f);
            char label[48];
            std::snprintf(label, sizeof label, "max %.3f N", top);
            ImGui::PlotLines("##force", h.forcePlot.data(), static_cast<int>(h.forcePlot.size()), 0, label, 0.0f,
                             top > 0 ? 1.1f * top : 1.0f, ImVec2(220, 60));
        }
        ImGui::End();
    };

    // An auto-resized window takes the size of its previous frame's content (and a new one is
    // hidden on its first frame): lay it out once without drawing, so a line added this frame (a
    // cut's answered count) is inside the panel (layout only: nothing is drawn).
    if (opts_.hud) {
        ImGui_ImplOpenGL3_NewFrame();
        ImGui::NewFrame();
        hudWindow();
        ImGui::Render();
    }

    ImGui_ImplOpenGL3_NewFrame();
    ImGui::NewFrame();
    if (opts_.hud) hudWindow();
    if (legend) {
        // Colour bar: one gradient quad per pair of control points, so the bar is exactly the map.
        ImDrawList* dl = ImGui::GetBackgroundDrawList();
        const PixelRect r = legendRect();
        auto table = colorMapTable(snap.diverging ? ColorMapKind::Diverging : ColorMapKind::Sequential);
        const int segs = static_cast<int>(table.size()) - 1;
        auto col = [](Rgb8 c) { return IM_COL32(c.r, c.g, c.b, 255); };
        for (int i = 0; i < segs; ++i) {
            const float yb = r.y1 - (r.y1 - r.y0) * float(i) / float(segs);
            const float yt = r.y1 - (r.y1 - r.y0) * float(i + 1) / float(segs);
            const ImU32 lo = col(table[static_cast<size_t>(i)]), hi = col(table[static_cast<size_t>(i + 1)]);
            dl->AddRectFilledMultiColor(ImVec2(r.x0, yt), ImVec2(r.x1, yb), hi, hi, lo, lo);
        }
        dl->AddRect(ImVec2(r.x0 - 1, r.y0 - 1), ImVec2(r.x1 + 1, r.y1 + 1), IM_COL32(220, 220, 220, 255));
        // Ticks at the ends, quarters and middle.
        const ImU32 text = IM_COL32(235, 235, 235, 255);
        const float lineH = ImGui::GetTextLineHeight();
        for (int k = 0; k <= 4; ++k) {
            const float y = r.y1 - (r.y1 - r.y0) * float(k) / 4.0f;
            const double v = snap.scalarMin + (snap.scalarMax - snap.scalarMin) * k / 4.0;
            char buf[32];
            std::snprintf(buf, sizeof buf, "%.3g",
                          std::abs(v) < 1e-12 * std::abs(snap.scalarMax - snap.scalarMin) ? 0.0 : v);
            dl->AddLine(ImVec2(r.x1, y), ImVec2(r.x1 + 4, y), text);
            dl->AddText(ImVec2(r.x1 + 7, y - 0.5f * lineH), text, buf);
        }
        std::string title = snap.scalarName;
        if (!snap.scalarUnit.empty()) title += " [" + snap.scalarUnit + "]";
        if (!title.empty()) {
            const float tw = ImGui::CalcTextSize(title.c_str()).x;
            const float x = std::max(4.0f, std::min(r.x0, static_cast<float>(opts_.width) - tw - 6.0f));
            dl->AddText(ImVec2(x, r.y0 - lineH - 6), text, title.c_str());
        }
    }
    if (critLegend) {
        // Swatches under the colour bar: the critical elements, how many and the step they would
        // allow; the ones a recent cut made critical and the step policy answered.
        ImDrawList* dl = ImGui::GetBackgroundDrawList();
        const PixelRect r = legendRect();
        const float lineH = ImGui::GetTextLineHeight();
        const ImU32 text = IM_COL32(235, 235, 235, 255);
        float y = r.y1 + lineH + 2;
        auto swatch = [&](const std::array<std::uint8_t, 3>& c, const char* line1, const char* line2) {
            const float w = std::max(ImGui::CalcTextSize(line1).x, ImGui::CalcTextSize(line2).x) + lineH + 4;
            const float x = std::max(4.0f, std::min(r.x0, static_cast<float>(opts_.width) - w - 4.0f));
            dl->AddRectFilled(ImVec2(x, y + 2), ImVec2(x + lineH - 4, y + lineH - 2), IM_COL32(c[0], c[1], c[2], 255));
            dl->AddText(ImVec2(x + lineH, y), text, line1);
            y += lineH;
            if (line2[0]) {
                dl->AddText(ImVec2(x, y), text, line2);
                y += lineH;
            }
        };
        char line1[48], line2[48];
        if (critical > 0) {
            std::snprintf(line1, sizeof line1, "critical %d", critical);
            if (std::isnan(snap.hud.criticalStep))
                line2[0] = 0;
            else
                std::snprintf(line2, sizeof line2, "dt<=%.2e s", snap.hud.criticalStep);
            swatch(opts_.criticalColour, line1, line2);
        }
        if (answered > 0) {
            std::snprintf(line1, sizeof line1, "answered %d", answered);
            swatch(opts_.answeredColour, line1, "");
        }
    }
    ImGui::Render();
    ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
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
    glReadPixels(0, 0, img.width, img.height, GL_RGBA, GL_UNSIGNED_BYTE, img.rgba.data());
    glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    // GL's first row is the bottom one: flip in place (no second frame-sized buffer per frame).
    const size_t row = 4 * static_cast<size_t>(img.width);
    for (int y = 0; y < img.height / 2; ++y)
        std::swap_ranges(img.rgba.begin() + static_cast<std::ptrdiff_t>(row * static_cast<size_t>(y)),
                         img.rgba.begin() + static_cast<std::ptrdiff_t>(row * static_cast<size_t>(y + 1)),
                         img.rgba.begin() + static_cast<std::ptrdiff_t>(row * static_cast<size_t>(img.height - 1 - y)));
}

}  // namespace cutsim::render
