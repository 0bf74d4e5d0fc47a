// A fine surface carried by a tet mesh (object.visual): each vertex rides the element holding it in
// the rest shape, at its barycentric weights, as SOFA's barycentric mapping of a visual model. A
// fine surface never lies exactly on the tet boundary; a vertex outside every element rides the
// nearest one with its weights extrapolated (some negative), which keeps the surface smooth.
#pragma once

#include "mesh/embedding.hpp"
#include "mesh/mesh.hpp"

namespace cutsim {

struct VisualEmbedding {
    EmbeddedSurface surface;  // unreferenced vertices of the file dropped
    int outside = 0;          // vertices in no element of the rest shape
    double maxOutside = 0;    // distance of the farthest of them from its element [m]
    int farthest = -1;        // that vertex (index in `surface`), -1 when none is outside
};

// Embeds `s` (rest positions) in the elements `tets` of rest nodes X. Point queries on a bounding
// volume tree of the elements; the nearest element of an outside vertex by a growing box search.
VisualEmbedding embedVisual(const SurfaceMesh& s, const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& X);

}  // namespace cutsim
