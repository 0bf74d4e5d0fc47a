#include "mesh/embedding.hpp"

#include "mesh/mesh.hpp"

#include <Eigen/LU>

#include <cassert>
#include <utility>

namespace cutsim {

EmbeddedSurface makeEmbeddedSurface(std::vector<int> element, const std::vector<Eigen::Vector4d>& weights,
                                    const std::vector<Eigen::Vector3i>& triangles, std::vector<int> cutId) {
    // Fixed-size Eigen vectors are stored contiguously, so the lists are the matrices' columns.
    EmbeddedSurface out;
    out.element = std::move(element);
    out.weights = Eigen::Map<const Eigen::Matrix4Xd>(weights.empty() ? nullptr : weights[0].data(), 4,
                                                     static_cast<Eigen::Index>(weights.size()));
    out.triangles = Eigen::Map<const Eigen::Matrix3Xi>(triangles.empty() ? nullptr : triangles[0].data(), 3,
                                                       static_cast<Eigen::Index>(triangles.size()));
    out.cutId = std::move(cutId);
    return out;
}

void embeddedPositions(const EmbeddedSurface& s, const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& x,
                       Eigen::Matrix3Xd& out) {
    const int nv = s.vertices();
    out.resize(3, nv);
    for (int v = 0; v < nv; ++v) {
        const int e = s.element[static_cast<size_t>(v)];
        out.col(v) = s.weights(0, v) * x.col(tets(0, e)) + s.weights(1, v) * x.col(tets(1, e)) +
                     s.weights(2, v) * x.col(tets(2, e)) + s.weights(3, v) * x.col(tets(3, e));
    }
}

Eigen::Vector4d barycentric(const Eigen::Vector3d& p, const Eigen::Vector3d& X0, const Eigen::Vector3d& X1,
                            const Eigen::Vector3d& X2, const Eigen::Vector3d& X3) {
    Eigen::Matrix3d Dm;
    Dm << X1 - X0, X2 - X0, X3 - X0;
    const Eigen::Vector3d w = Dm.inverse() * (p - X0);
    return {1.0 - w.sum(), w[0], w[1], w[2]};
}

EmbeddedSurface boundarySurface(const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& X) {
    TetMesh m;
    m.X = X;
    m.tets = tets;
    const Eigen::Matrix3Xi bf = boundaryFaces(m);

    // Element of each boundary face: the face opposite the corner not on it.
    std::vector<int> nodeElem(static_cast<size_t>(X.cols()), -1), nodeCorner(static_cast<size_t>(X.cols()), -1);
    for (int e = 0; e < tets.cols(); ++e)
        for (int a = 0; a < 4; ++a) {
            const auto n = static_cast<size_t>(tets(a, e));
            if (nodeElem[n] < 0) {
                nodeElem[n] = e;
                nodeCorner[n] = a;
            }
        }

    EmbeddedSurface s;
    std::vector<int> vertexOf(static_cast<size_t>(X.cols()), -1);
    s.triangles.resize(3, bf.cols());
    for (int f = 0; f < bf.cols(); ++f)
        for (int k = 0; k < 3; ++k) {
            const auto n = static_cast<size_t>(bf(k, f));
            int& v = vertexOf[n];
            if (v < 0) {
                v = s.vertices();
                s.element.push_back(nodeElem[n]);
            }
            s.triangles(k, f) = v;
        }
    s.weights = Eigen::Matrix4Xd::Zero(4, s.vertices());
    for (size_t n = 0; n < vertexOf.size(); ++n)
        if (vertexOf[n] >= 0) s.weights(nodeCorner[n], vertexOf[n]) = 1.0;
    s.cutId.assign(static_cast<size_t>(bf.cols()), -1);
    return s;
}

int dominantNode(const EmbeddedSurface& s, const Eigen::Matrix4Xi& tets, int vertex) {
    Eigen::Index a = 0;
    s.weights.col(vertex).maxCoeff(&a);
    return tets(static_cast<int>(a), s.element[static_cast<size_t>(vertex)]);
}

}  // namespace cutsim
