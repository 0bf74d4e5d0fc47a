#include "mesh/mesh.hpp"

#include <algorithm>
#include <array>
#include <map>
#include <unordered_map>

namespace cutsim {

SurfaceCleanup cleanSurface(SurfaceMesh& s, double minArea) {
    SurfaceCleanup c;
    std::map<std::array<double, 3>, int> at;
    std::vector<int> to(static_cast<size_t>(s.vertices()));
    for (int i = 0; i < s.vertices(); ++i) {
        const auto [it, fresh] = at.try_emplace({s.V(0, i), s.V(1, i), s.V(2, i)}, i);
        to[static_cast<size_t>(i)] = it->second;
        c.weldedVertices += fresh ? 0 : 1;
    }
    std::map<std::array<int, 3>, int> seen;
    int kept = 0;
    for (int f = 0; f < s.faces(); ++f) {
        std::array<int, 3> v{};
        for (int k = 0; k < 3; ++k) v[k] = to[static_cast<size_t>(s.F(k, f))];
        const double area = 0.5 * (s.V.col(v[1]) - s.V.col(v[0])).cross(s.V.col(v[2]) - s.V.col(v[0])).norm();
        if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2] || !(area > minArea)) {
            ++c.degenerateFaces;
            continue;
        }
        std::array<int, 3> key = v;
        std::sort(key.begin(), key.end());
        if (!seen.emplace(key, f).second) {
            ++c.duplicateFaces;
            continue;
        }
        s.F.col(kept++) = Eigen::Vector3i(v[0], v[1], v[2]);
    }
    s.F.conservativeResize(3, kept);
    return c;
}

double tetSignedVolume(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                       const Eigen::Vector3d& d) {
    return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

double tetSignedVolume(const TetMesh& m, int e) {
    return tetSignedVolume(m.X.col(m.tets(0, e)), m.X.col(m.tets(1, e)), m.X.col(m.tets(2, e)), m.X.col(m.tets(3, e)));
}

Eigen::Matrix3Xi boundaryFaces(const TetMesh& m) {
    // Faces opposite node 0..3, wound so the normal points away from the opposite node
    // for a positively oriented tet.
    static constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    struct Entry {
        std::array<int, 3> f;
        int count;
    };
    std::map<std::array<int, 3>, Entry> faces;
    for (int e = 0; e < m.elements(); ++e) {
        const bool flip = tetSignedVolume(m, e) < 0;
        for (const auto& lf : kFace) {
            std::array<int, 3> f{m.tets(lf[0], e), m.tets(lf[1], e), m.tets(lf[2], e)};
            if (flip) std::swap(f[1], f[2]);
            std::array<int, 3> key = f;
            std::sort(key.begin(), key.end());
            auto [it, inserted] = faces.try_emplace(key, Entry{f, 0});
            ++it->second.count;
        }
    }
    std::vector<std::array<int, 3>> out;
    for (const auto& [key, entry] : faces)
        if (entry.count == 1) out.push_back(entry.f);
    Eigen::Matrix3Xi F(3, static_cast<Eigen::Index>(out.size()));
    for (size_t i = 0; i < out.size(); ++i) F.col(static_cast<Eigen::Index>(i)) << out[i][0], out[i][1], out[i][2];
    return F;
}

double totalVolume(const TetMesh& m) {
    double v = 0;
    for (int e = 0; e < m.elements(); ++e) v += std::abs(tetSignedVolume(m, e));
    return v;
}

double enclosedVolume(const SurfaceMesh& s) {
    double v = 0;
    for (int f = 0; f < s.faces(); ++f) {
        const Eigen::Vector3d a = s.V.col(s.F(0, f)), b = s.V.col(s.F(1, f)), c = s.V.col(s.F(2, f));
        v += a.dot(b.cross(c)) / 6.0;
    }
    return v;
}

TetMesh subMesh(const TetMesh& m, const std::vector<int>& elements, std::vector<int>& nodeOf) {
    TetMesh sub;
    std::vector<int> local(static_cast<size_t>(m.nodes()), -1);
    nodeOf.clear();
    sub.tets.resize(4, static_cast<Eigen::Index>(elements.size()));
    for (size_t k = 0; k < elements.size(); ++k)
        for (int a = 0; a < 4; ++a) {
            const int i = m.tets(a, elements[k]);
            int& l = local[static_cast<size_t>(i)];
            if (l < 0) l = static_cast<int>(nodeOf.size()), nodeOf.push_back(i);
            sub.tets(a, static_cast<Eigen::Index>(k)) = l;
        }
    sub.X.resize(3, static_cast<Eigen::Index>(nodeOf.size()));
    for (size_t l = 0; l < nodeOf.size(); ++l) sub.X.col(static_cast<Eigen::Index>(l)) = m.X.col(nodeOf[l]);
    return sub;
}

}  // namespace cutsim
