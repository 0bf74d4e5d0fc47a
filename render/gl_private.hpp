// The Renderer's GL objects, mesh program state and per-frame view, shared by its sources
// (renderer.cpp draws the scene, hud.cpp the HUD and legend, gl_objects.cpp holds the shaders).
// Private to render/: not part of the installed API.
#pragma once

#include "geometry.hpp"
#include "gl.hpp"
#include "renderer.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

struct ImGuiContext;

#ifndef GL_PACK_INVERT_MESA
#define GL_PACK_INVERT_MESA 0x8758  // GL_MESA_pack_invert (not in glcorearb.h)
#endif

namespace cutsim::render {

// Alpha blending that leaves the frame opaque: a frame read back with alpha under 1 shows lighter
// wherever a viewer composites the PNG over white.
void blendOver();

// GL objects.
struct Renderer::Gl {
    GLuint msFbo = 0, msColour = 0, msDepth = 0;     // multisampled target (MSAA)
    GLuint outFbo = 0, outColour = 0, outDepth = 0;  // read back; drawn into directly with one sample
    GLuint lineProg = 0;
    GLuint vao = 0;
    bool packInvert = false;  // GL_MESA_pack_invert: glReadPixels can give the top row first
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
        Eigen::Matrix4f view = Eigen::Matrix4f::Identity(), proj = Eigen::Matrix4f::Identity();
        std::array<float, 16 * 3> map{};
        int mapN = 2;
        float min = 0, max = 1;
        bool useMap = false, lit = true;
        Eigen::Vector3f colour = Eigen::Vector3f::Ones(), cutColour = Eigen::Vector3f::Ones();
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
    // The background and floor of a still camera (Renderer::drawBackground), and what they were
    // drawn for.
    struct Still {
        GLuint fbo = 0, colour = 0;
        int width = 0, height = 0;  // of `colour`
        bool valid = false;
        std::vector<float> drawn, last, key;  // the layer's key; the last frame's; this frame's
    } still;

    void makeLineProgram();  // lineProg and its uniforms; throws std::runtime_error
    // Binds the mesh program variant for `ms` with its uniforms.
    void useMeshProgram();
    // Binds the next buffer of this frame with `bytes` of data.
    void upload(const void* data, GLsizeiptr bytes);
    // Uploads and draws interleaved mesh vertices (triangles, or segments with GL_LINES).
    void drawMesh(const std::vector<MeshVertex>& v, GLenum mode = GL_TRIANGLES);
    // Uploads and draws line segments (xyz pairs).
    void drawLines(const std::vector<float>& l);
};

// The camera and the scene's extent for one frame.
struct Renderer::View {
    Eigen::Matrix4f view, proj;
    Eigen::Vector3d centre = Eigen::Vector3d::Zero(), up = Eigen::Vector3d::UnitZ();
    double radius = 1;
    float zNear = 0, zFar = 0;  // of proj
    Eigen::Vector3f bg = Eigen::Vector3f::Zero();
};

}  // namespace cutsim::render
