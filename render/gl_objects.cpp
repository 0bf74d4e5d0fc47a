#include "gl_private.hpp"

#include <stdexcept>
#include <string>

namespace cutsim::render {
namespace {

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

}  // namespace

void blendOver() {
    glEnable(GL_BLEND);
    glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ZERO, GL_ONE);
}

void Renderer::Gl::makeLineProgram() {
    lineProg = link(kLineVs, kLineFs);
    lView = glGetUniformLocation(lineProg, "uView");
    lProj = glGetUniformLocation(lineProg, "uProj");
    lColour = glGetUniformLocation(lineProg, "uColour");
}

void Renderer::Gl::useMeshProgram() {
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

void Renderer::Gl::upload(const void* data, GLsizeiptr bytes) {
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
void Renderer::Gl::drawMesh(const std::vector<MeshVertex>& v, GLenum mode) {
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
void Renderer::Gl::drawLines(const std::vector<float>& l) {
    if (l.empty()) return;
    upload(l.data(), static_cast<GLsizeiptr>(l.size() * sizeof(float)));
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
    for (GLuint a = 1; a < 6; ++a) glDisableVertexAttribArray(a);
    glDrawArrays(GL_LINES, 0, static_cast<GLsizei>(l.size() / 3));
}

}  // namespace cutsim::render
