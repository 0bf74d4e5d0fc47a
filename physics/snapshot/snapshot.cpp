#include "snapshot/snapshot.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <utility>

namespace cutsim {
namespace {

// Tet edges as pairs of local corners.
constexpr int kTetEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};

// Unique edges of all tets, each once (2 x nEdges of node indices).
std::vector<std::pair<int, int>> uniqueEdges(const TetMesh& mesh) {
    std::vector<std::pair<int, int>> e;
    e.reserve(6 * static_cast<size_t>(mesh.elements()));
    for (int t = 0; t < mesh.elements(); ++t)
        for (const auto& k : kTetEdges) {
            int a = mesh.tets(k[0], t), b = mesh.tets(k[1], t);
            e.emplace_back(std::min(a, b), std::max(a, b));
        }
    std::sort(e.begin(), e.end());
    e.erase(std::unique(e.begin(), e.end()), e.end());
    return e;
}

// Fills the position-dependent parts from x.
void fillPositions(MeshSnapshot& ms, const TetMesh& mesh, const Eigen::Matrix3Xd& x, const MeshSnapshotOptions& opts) {
    RenderSnapshot& s = ms.snap;
    embeddedPositions(ms.surface, mesh.tets, x, s.positions);
    s.normals.resize(3, 0);  // recomputed by the renderer
    if (opts.wireframe) {
        auto e = uniqueEdges(mesh);
        s.edges.resize(3, 2 * static_cast<int>(e.size()));
        for (size_t i = 0; i < e.size(); ++i) {
            s.edges.col(2 * static_cast<int>(i)) = x.col(e[i].first);
            s.edges.col(2 * static_cast<int>(i) + 1) = x.col(e[i].second);
        }
    } else {
        s.edges.resize(3, 0);
    }
    s.criticalTets.resize(3, 4 * static_cast<int>(opts.critical.size()));
    for (size_t i = 0; i < opts.critical.size(); ++i)
        for (int a = 0; a < 4; ++a)
            s.criticalTets.col(4 * static_cast<int>(i) + a) = x.col(mesh.tets(a, opts.critical[i]));
}

}  // namespace

void setElementValues(MeshSnapshot& ms, const TetMesh& mesh, const MeshSnapshotOptions& opts) {
    // Per-vertex value: mean over the elements around the node (the simplest smoothing that keeps
    // the range of the element values).
    if (!opts.elementValues) return;
    RenderSnapshot& s = ms.snap;
    const Eigen::VectorXd& ev = *opts.elementValues;
    assert(ev.size() == mesh.elements());
    Eigen::VectorXd sum = Eigen::VectorXd::Zero(mesh.nodes());
    Eigen::VectorXi count = Eigen::VectorXi::Zero(mesh.nodes());
    for (int t = 0; t < mesh.elements(); ++t)
        for (int a = 0; a < 4; ++a) {
            sum[mesh.tets(a, t)] += ev[t];
            ++count[mesh.tets(a, t)];
        }
    const int nv = ms.surface.vertices();
    s.scalar.resize(nv);
    for (int v = 0; v < nv; ++v) {
        const int n = dominantNode(ms.surface, mesh.tets, v);
        s.scalar[v] = sum[n] / std::max(1, count[n]);
    }
    s.scalarName = opts.name;
    s.scalarUnit = opts.unit;
    s.diverging = opts.diverging;
    double lo = ev.size() ? ev[0] : 0.0, hi = ev.size() ? ev[0] : 1.0;
    for (Eigen::Index t = 1; t < ev.size(); ++t) {
        lo = std::min(lo, ev[t]);
        hi = std::max(hi, ev[t]);
    }
    if (opts.diverging) {
        double m = std::max(std::abs(lo), std::abs(hi));
        lo = -m;
        hi = m;
    }
    if (!(hi > lo)) {  // constant field: a range around it so the map stays defined
        double pad = std::max(std::abs(lo) * 1e-3, 1e-30);
        lo -= pad;
        hi += pad;
    }
    s.scalarMin = lo;
    s.scalarMax = hi;
}

MeshSnapshot snapshotFromTetMesh(const TetMesh& mesh, const MeshSnapshotOptions& opts) {
    return snapshotFromTetMesh(mesh, mesh.X, opts);
}

MeshSnapshot snapshotFromTetMesh(const TetMesh& mesh, const Eigen::Matrix3Xd& x, const MeshSnapshotOptions& opts) {
    return snapshotFromSurface(mesh, x, boundarySurface(mesh.tets, mesh.X), opts);
}

MeshSnapshot snapshotFromSurface(const TetMesh& mesh, const Eigen::Matrix3Xd& x, EmbeddedSurface surface,
                                 const MeshSnapshotOptions& opts) {
    assert(x.cols() == mesh.nodes());
    MeshSnapshot ms;
    RenderSnapshot& s = ms.snap;
    ms.surface = std::move(surface);
    s.triangles = ms.surface.triangles;
    s.cutFace.assign(static_cast<size_t>(s.triangles.cols()), 0);
    for (size_t t = 0; t < std::min(s.cutFace.size(), ms.surface.cutId.size()); ++t)
        s.cutFace[t] = ms.surface.cutId[t] >= 0;

    setElementValues(ms, mesh, opts);

    fillPositions(ms, mesh, x, opts);

    // Camera framing the deformed surface.
    // (scalar loops, not Eigen min/max: GCC 12 warns inside Eigen's AVX-512 path)
    if (s.positions.cols() > 0) {
        Eigen::Vector3d lo = s.positions.col(0), hi = lo;
        for (int v = 1; v < s.positions.cols(); ++v) {
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], s.positions(k, v));
                hi[k] = std::max(hi[k], s.positions(k, v));
            }
        }
        s.camera = frameBox(lo, hi);
    }
    s.hud.criticalElements = static_cast<int>(opts.critical.size());
    return ms;
}

void updateSnapshotPositions(MeshSnapshot& ms, const TetMesh& mesh, const Eigen::Matrix3Xd& x,
                             const MeshSnapshotOptions& opts) {
    fillPositions(ms, mesh, x, opts);
}

Camera frameBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, const Eigen::Vector3d& up) {
    Camera c;
    c.up = up.normalized();
    c.target = 0.5 * (lo + hi);
    const double radius = std::max(0.5 * (hi - lo).norm(), 1e-9);
    // View direction from front-right and 30 degrees above, built from up so any up axis works.
    Eigen::Vector3d side = c.up.unitOrthogonal();
    Eigen::Vector3d front = c.up.cross(side);
    Eigen::Vector3d dir = (0.8 * front + 0.6 * side).normalized();
    dir = (std::cos(M_PI / 6) * dir + std::sin(M_PI / 6) * c.up).normalized();
    // Distance so the bounding sphere fits the vertical field of view, with a margin.
    const double half = 0.5 * c.fovY * M_PI / 180.0;
    c.eye = c.target + dir * (1.1 * radius / std::sin(half));
    return c;
}

double niceGridStep(double x) {
    const double p = std::pow(10.0, std::floor(std::log10(x)));
    const double m = x / p;
    return (m >= 5 ? 5 : m >= 2 ? 2 : 1) * p;
}

}  // namespace cutsim
