// Triangle and segment geometry the renderer draws: the surface's corners with their normals, tool
// solids, critical elements, silhouettes and screen-space quads for smoothed segments. No GL here.
#pragma once

#include "snapshot/snapshot.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <utility>
#include <vector>

namespace cutsim::render {

// Interleaved vertex of the mesh program: position, normal, scalar, cut flag.
struct MeshVertex {
    float p[3], n[3], s, cut;
    float edge = 0;         // smoothed segments: signed distance from the centre line [px]
    float off[2] = {0, 0};  // and the corner's offset in normalised device coordinates
};

// Appends triangle abc with its face normal.
void pushTriangle(std::vector<MeshVertex>& out, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                  const Eigen::Vector3d& c);

// Tool solids as flat triangles in world coordinates.
void toolTriangles(const ToolShape& t, std::vector<MeshVertex>& out);

// What a surface's triangles alone give (no positions): the faces around each vertex and the
// corners of each edge, kept between frames and rebuilt only when the triangles change (a cut).
struct SurfaceTopology {
    Eigen::Matrix3Xi triangles;                       // what it was built from
    int vertices = -1;                                // and their vertex count
    std::vector<int> start, faces;                    // vertex v's faces: faces[start[v] .. start[v + 1])
    std::vector<std::pair<std::uint64_t, int>> half;  // (edge key, corner) sorted: see silhouetteLines
    // Rebuilds for snap's triangles when they differ from the last ones; true when it did.
    bool update(const RenderSnapshot& snap);
};

// The surface's triangle corners (3 per face, in face order) with smooth normals within the crease
// angle, the scalar when useMap, and the cut flag; topo is snap's (SurfaceTopology::update).
void surfaceVertices(const RenderSnapshot& snap, const SurfaceTopology& topo, bool useMap,
                     std::vector<MeshVertex>& verts);

// The silhouette of a triangle soup seen from `eye` as corner pairs (see geometry.cpp); ids[c]
// names corner c's vertex, or is recomputed from positions when its size differs from the soup's.
void silhouetteLines(const std::vector<MeshVertex>& soup, std::vector<int>& ids, const Eigen::Vector3f& eye,
                     std::vector<std::pair<std::uint64_t, int>>& half, std::vector<MeshVertex>& out);
// The same with the soup's edges already sorted (halfEdges of its ids).
void silhouetteLines(const std::vector<MeshVertex>& soup, const std::vector<std::pair<std::uint64_t, int>>& half,
                     const Eigen::Vector3f& eye, std::vector<MeshVertex>& out);
// Each corner c of a soup with corner ids `ids` as (key of the edge from c to the next corner of
// its face, c), sorted: the corners of one edge are neighbours.
void halfEdges(const std::vector<int>& ids, std::vector<std::pair<std::uint64_t, int>>& half);

// Corner pairs as screen-space quads for smoothed drawing (see geometry.cpp); width, height: half
// the frame's size [px].
void segmentQuads(const std::vector<MeshVertex>& segs, const Eigen::Matrix4f& pv, float width, float height,
                  float halfWidth, std::vector<MeshVertex>& out);

// Tets given by their corners (4 columns each): faces (triangles) and edges (xyz pairs).
void tetGeometry(const Eigen::Matrix3Xd& corners, std::vector<MeshVertex>& tris, std::vector<float>& lines);

}  // namespace cutsim::render
