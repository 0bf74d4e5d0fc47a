// Step statistics of a mesh and the distance between two meshes' boundaries: what the mesh
// improver (improve.cpp) reports.
#include "improve/stats.hpp"

#include "embed/clip.hpp"
#include "fem/model.hpp"
#include "fem/tet.hpp"
#include "timestep/timestep.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace cutsim {
namespace {

using Vec3 = Eigen::Vector3d;
constexpr double kPi = 3.14159265358979323846;

double minDihedralDeg(const TetMesh& m) {
    static constexpr int kEdges[6][4] = {{0, 1, 2, 3}, {0, 2, 1, 3}, {0, 3, 1, 2},
                                         {1, 2, 0, 3}, {1, 3, 0, 2}, {2, 3, 0, 1}};
    double best = 180;
    for (int e = 0; e < m.elements(); ++e) {
        for (const auto& ed : kEdges) {
            const Vec3 p = m.X.col(m.tets(ed[0], e)), q = m.X.col(m.tets(ed[1], e));
            const Vec3 r = m.X.col(m.tets(ed[2], e)), s = m.X.col(m.tets(ed[3], e));
            const Vec3 axis = (q - p).normalized();
            Vec3 u = r - p, v = s - p;
            u -= axis * axis.dot(u);
            v -= axis * axis.dot(v);
            const double c = u.dot(v) / std::max(u.norm() * v.norm(), 1e-300);
            best = std::min(best, std::acos(std::clamp(c, -1.0, 1.0)) * 180 / kPi);
        }
    }
    return best;
}

}  // namespace

MeshStepStats meshStepStats(const TetMesh& mesh, const Material& material) { return stepStats(mesh, material, 0); }

MeshStepStats stepStats(const TetMesh& mesh, const Material& material, double dtExact) {
    MeshStepStats s;
    const Model m = buildModel(mesh, material);
    const StiffnessRows rows = assembleStiffnessRows(m);
    s.nodes = m.nodes();
    s.tets = m.elements();
    s.dtExact = dtExact > 0 ? dtExact : exactCriticalDt(m, rows).dt;
    s.dtCertified = certifiedDt(m, rows);
    ElementEstimates est;
    estimateElements(m, rows, assembleStiffnessDiagonal(m), nullptr, est);
    s.dtR1R = est.r1r.size() ? est.r1r.minCoeff() : 0.0;
    s.minDihedralDeg = minDihedralDeg(mesh);
    s.volume = totalVolume(mesh);
    return s;
}

MeshStepStats r1rStats(const TetMesh& mesh, double dtR1R) {
    MeshStepStats s;
    s.nodes = mesh.nodes();
    s.tets = mesh.elements();
    s.dtR1R = dtR1R;
    s.volume = totalVolume(mesh);
    return s;
}

double surfaceDistance(const TetMesh& from, const TetMesh& to) {
    const Eigen::Matrix3Xi F = boundaryFaces(from), G = boundaryFaces(to);
    // Each old face's bounding sphere prunes the exact point-triangle distances.
    std::vector<Vec3> centre(F.cols());
    std::vector<double> radius(F.cols());
    for (int f = 0; f < F.cols(); ++f) {
        centre[f] = (from.X.col(F(0, f)) + from.X.col(F(1, f)) + from.X.col(F(2, f))) / 3;
        radius[f] = 0;
        for (int k = 0; k < 3; ++k) radius[f] = std::max(radius[f], (from.X.col(F(k, f)) - centre[f]).norm());
    }
    auto distance = [&](const Vec3& p) {
        double best = std::numeric_limits<double>::infinity();
        for (int f = 0; f < F.cols(); ++f) {
            if ((p - centre[f]).norm() - radius[f] >= best) continue;
            const Vec3 c = closestPointOnTriangle(p, from.X.col(F(0, f)), from.X.col(F(1, f)), from.X.col(F(2, f)));
            best = std::min(best, (c - p).norm());
        }
        return best;
    };
    double worst = 0;
    for (int g = 0; g < G.cols(); ++g) {
        const Vec3 p0 = to.X.col(G(0, g)), p1 = to.X.col(G(1, g)), p2 = to.X.col(G(2, g));
        for (const Vec3& s :
             {p0, p1, p2, Vec3((p0 + p1) / 2), Vec3((p1 + p2) / 2), Vec3((p2 + p0) / 2), Vec3((p0 + p1 + p2) / 3)})
            worst = std::max(worst, distance(s));
    }
    return worst;
}

}  // namespace cutsim
