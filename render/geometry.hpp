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

// The surface's triangle corners (3 per face, in face order) with smooth normals within the crease
// angle, the scalar when useMap, and the cut flag.
void surfaceVertices(const RenderSnapshot& snap, bool useMap, std::vector<MeshVertex>& verts);

// The silhouette of a triangle soup seen from `eye` as corner pairs (see geometry.cpp); ids[c]
// names corner c's vertex, or is recomputed from positions when its size differs from the soup's.
void silhouetteLines(const std::vector<MeshVertex>& soup, std::vector<int>& ids, const Eigen::Vector3f& eye,
                     std::vector<std::pair<std::uint64_t, int>>& half, std::vector<MeshVertex>& out);

// Corner pairs as screen-space quads for smoothed drawing (see geometry.cpp); width, height: half
// the frame's size [px].
void segmentQuads(const std::vector<MeshVertex>& segs, const Eigen::Matrix4f& pv, float width, float height,
                  float halfWidth, std::vector<MeshVertex>& out);

// Tets given by their corners (4 columns each): faces (triangles) and edges (xyz pairs).
void tetGeometry(const Eigen::Matrix3Xd& corners, std::vector<MeshVertex>& tris, std::vector<float>& lines);

}  // namespace cutsim::render
