#include "fem/model.hpp"
#include "util/union_find.hpp"

#include "fem/tet.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>
#include <utility>

namespace cutsim {

int Model::freeDofs() const {
    int n = 0;
    for (int i = 0; i < nodes(); ++i) n += invMass(i) > 0 ? 3 : 0;
    return n;
}

Model buildModel(const TetMesh& mesh, const Material& material, ElementModel elementModel) {
    if (!material.valid()) throw InputError("material: need E > 0, -1 < nu < 0.5, rho > 0");
    Model m;
    m.material = material;
    m.elementModel = elementModel;
    m.X = mesh.X;
    m.tets = mesh.tets;
    const int ne = mesh.elements();
    m.DmInv.resize(9, ne);
    m.volume.resize(ne);
    m.fraction = Eigen::VectorXd::Ones(ne);
    for (int e = 0; e < ne; ++e) {
        Mat34 Xe;
        for (int a = 0; a < 4; ++a) {
            const int n = mesh.tets(a, e);
            if (n < 0 || n >= mesh.nodes())
                throw InputError(mesh.source, 0,
                                 "element " + std::to_string(e) + " refers to node " + std::to_string(n) +
                                     " which does not exist");
            Xe.col(a) = mesh.X.col(n);
        }
        const Eigen::Matrix3d Dm = restShapeMatrix(Xe);
        const double V = Dm.determinant() / 6.0;
        if (!(V > 0))
            throw InputError(mesh.source, 0,
                             "element " + std::to_string(e) + (V < 0 ? " is inverted" : " has zero volume"));
        const Eigen::Matrix3d inv = Dm.inverse();
        std::copy(inv.data(), inv.data() + 9, m.DmInv.col(e).data());
        m.volume(e) = V;
    }
    m.fixed.assign(mesh.nodes(), 0);
    updateMasses(m);
    buildIncidence(m);
    return m;
}

void updateMasses(Model& m) {
    m.mass = Eigen::VectorXd::Zero(m.nodes());
    const double rho = m.material.rho;
    const bool shares = m.massShare.cols() == m.elements();
    for (int e = 0; e < m.elements(); ++e) {
        const double me = rho * m.volume(e) * m.fraction(e) / 4.0;
        for (int a = 0; a < 4; ++a) m.mass(m.tets(a, e)) += shares ? rho * m.volume(e) * m.massShare(a, e) : me;
    }
    if (m.addedMass.size() == m.nodes()) m.mass += m.addedMass;
    m.invMass.resize(m.nodes());
    for (int i = 0; i < m.nodes(); ++i) m.invMass(i) = (m.fixed[i] || m.mass(i) <= 0) ? 0.0 : 1.0 / m.mass(i);
}

void updateMasses(Model& m, const std::vector<int>& nodes) {
    const int n = m.nodes();
    m.mass.conservativeResize(n);
    m.invMass.conservativeResize(n);
    const double rho = m.material.rho;
    const bool shares = m.massShare.cols() == m.elements(), added = m.addedMass.size() == n;
    for (int i : nodes) {
        double mi = 0;
        for (int sl = m.nodeSlotStart[i]; sl < m.nodeSlotEnd[i]; ++sl) {
            const int e = m.nodeSlots[sl] / 4, a = m.nodeSlots[sl] % 4;
            mi += shares ? rho * m.volume(e) * m.massShare(a, e) : rho * m.volume(e) * m.fraction(e) / 4.0;
        }
        if (added) mi += m.addedMass(i);
        m.mass(i) = mi;
        m.invMass(i) = (m.fixed[i] || mi <= 0) ? 0.0 : 1.0 / mi;
    }
}

Eigen::VectorXd wholeMass(const Model& m) {
    Eigen::VectorXd whole = Eigen::VectorXd::Zero(m.nodes());
    for (int e = 0; e < m.elements(); ++e)
        for (int a = 0; a < 4; ++a) whole(m.tets(a, e)) += m.material.rho * m.volume(e) / 4.0;
    return whole;
}

void markLightNodes(Model& m, const Eigen::VectorXd& reference, double share, const std::vector<int>* originalOf) {
    m.lightNodes.clear();
    if (share <= 0) return;
    for (int n = 0; n < m.nodes(); ++n) {
        const int o = originalOf ? (*originalOf)[static_cast<size_t>(n)] : n;
        if (m.invMass(n) > 0 && m.mass(n) < share * reference(o)) m.lightNodes.push_back(n);
    }
}

void fixNodes(Model& m, const std::vector<int>& nodes) {
    for (int n : nodes) m.fixed.at(n) = 1;
    updateMasses(m);
}

void buildIncidence(Model& m) {
    const size_t n = static_cast<size_t>(m.nodes());
    m.nodeSlotStart.assign(n, 0);
    for (int e = 0; e < m.elements(); ++e)
        for (int a = 0; a < 4; ++a) ++m.nodeSlotStart[static_cast<size_t>(m.tets(a, e))];
    int sum = 0;
    for (size_t i = 0; i < n; ++i) sum += std::exchange(m.nodeSlotStart[i], sum);
    // room for a cut's rows to move to the end without reallocating at once
    m.nodeSlots.reserve(4 * static_cast<size_t>(m.elements()) * 5 / 4 + 64);
    m.nodeSlots.resize(4 * static_cast<size_t>(m.elements()));
    m.nodeSlotEnd = m.nodeSlotStart;
    for (int e = 0; e < m.elements(); ++e)
        for (int a = 0; a < 4; ++a) m.nodeSlots[static_cast<size_t>(m.nodeSlotEnd[m.tets(a, e)]++)] = 4 * e + a;
}

void updateIncidence(Model& m, const std::vector<int>& rows, const std::vector<int>& elements) {
    const int n = m.nodes(), n0 = static_cast<int>(m.nodeSlotStart.size());
    if (n0 == 0 || n < n0 || m.nodeSlotEnd.size() != m.nodeSlotStart.size()) return buildIncidence(m);
    m.nodeSlotStart.resize(static_cast<size_t>(n), 0);  // appended nodes: empty rows until written
    m.nodeSlotEnd.resize(static_cast<size_t>(n), 0);
    std::vector<int> changed(elements);
    std::sort(changed.begin(), changed.end());
    changed.erase(std::unique(changed.begin(), changed.end()), changed.end());
    // the changed elements' slots by node
    std::vector<std::pair<int, int>> fresh;
    fresh.reserve(4 * changed.size());
    for (int e : changed)
        for (int a = 0; a < 4; ++a) fresh.emplace_back(m.tets(a, e), 4 * e + a);
    std::sort(fresh.begin(), fresh.end());
    std::vector<int> list;
    for (int i : rows) {
        if (i < 0 || i >= n) throw std::logic_error("updateIncidence: row " + std::to_string(i) + " is not a node");
        const size_t si = static_cast<size_t>(i);
        list.clear();
        // its slots of unchanged elements, then the changed elements' slots at it
        for (int k = m.nodeSlotStart[si]; k < m.nodeSlotEnd[si]; ++k) {
            const int slot = m.nodeSlots[static_cast<size_t>(k)];
            if (!std::binary_search(changed.begin(), changed.end(), slot >> 2)) list.push_back(slot);
        }
        for (auto it = std::lower_bound(fresh.begin(), fresh.end(), std::pair<int, int>{i, -1});
             it != fresh.end() && it->first == i; ++it)
            list.push_back(it->second);
        std::sort(list.begin(), list.end());
        list.erase(std::unique(list.begin(), list.end()), list.end());                  // a row listed twice
        if (static_cast<int>(list.size()) > m.nodeSlotEnd[si] - m.nodeSlotStart[si]) {  // grew: to the end
            m.nodeSlotStart[si] = static_cast<int>(m.nodeSlots.size());
            m.nodeSlots.insert(m.nodeSlots.end(), list.begin(), list.end());
        } else {
            std::copy(list.begin(), list.end(), m.nodeSlots.begin() + m.nodeSlotStart[si]);
        }
        m.nodeSlotEnd[si] = m.nodeSlotStart[si] + static_cast<int>(list.size());
    }
    // gaps over half the live slots (4 per element): rebuilt in node order
    if (m.nodeSlots.size() > 6 * static_cast<size_t>(m.elements()) + 1024) buildIncidence(m);
}

Eigen::SparseMatrix<double> assembleStiffness(const Model& m) {
    std::vector<Eigen::Triplet<double>> trips;
    trips.reserve(static_cast<size_t>(m.elements()) * 144);
    for (int e = 0; e < m.elements(); ++e) {
        const Mat12 K = elementStiffness(shapeGradients(m.dmInv(e)), m.stiffnessVolume(e), m.material);
        for (int a = 0; a < 4; ++a)
            for (int b = 0; b < 4; ++b)
                for (int i = 0; i < 3; ++i)
                    for (int j = 0; j < 3; ++j)
                        trips.emplace_back(3 * m.tets(a, e) + i, 3 * m.tets(b, e) + j, K(3 * a + i, 3 * b + j));
    }
    Eigen::SparseMatrix<double> K(3 * m.nodes(), 3 * m.nodes());
    K.setFromTriplets(trips.begin(), trips.end());
    return K;
}

std::vector<int> freeDofMap(const Model& m, int* nFree) {
    std::vector<int> map(3 * static_cast<size_t>(m.nodes()), -1);
    int nf = 0;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.invMass(i) > 0)
            for (int k = 0; k < 3; ++k) map[3 * static_cast<size_t>(i) + k] = nf++;
    *nFree = nf;
    return map;
}

Eigen::SparseMatrix<double> freeStiffness(const Model& m, const std::vector<int>& map, int nf,
                                          const Eigen::VectorXd* scale) {
    const Eigen::SparseMatrix<double> K = assembleStiffness(m);
    std::vector<Eigen::Triplet<double>> t;
    for (int c = 0; c < K.outerSize(); ++c)
        for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it) {
            const int r = map[static_cast<size_t>(it.row())], cc = map[static_cast<size_t>(it.col())];
            if (r >= 0 && cc >= 0) t.emplace_back(r, cc, scale ? it.value() * (*scale)(r) * (*scale)(cc) : it.value());
        }
    Eigen::SparseMatrix<double> Kf(nf, nf);
    Kf.setFromTriplets(t.begin(), t.end());
    return Kf;
}

Eigen::SparseMatrix<double> scaledFreeStiffness(const Model& m, const std::vector<int>& map, int nf) {
    Eigen::VectorXd s(nf);
    for (int i = 0; i < m.nodes(); ++i)
        for (int k = 0; k < 3; ++k)
            if (const int d = map[3 * static_cast<size_t>(i) + k]; d >= 0) s(d) = 1.0 / std::sqrt(m.mass(i));
    return freeStiffness(m, map, nf, &s);
}

TetMesh restMesh(const Model& m) {
    TetMesh mesh;
    mesh.X = m.X;
    mesh.tets = m.tets;
    mesh.source = "model";
    return mesh;
}

std::vector<double> pieceVolumes(const Model& m) {
    UnionFind uf = elementPieces(m.tets, m.nodes());
    std::vector<double> byRoot(static_cast<size_t>(m.nodes()), -1.0);
    for (int e = 0; e < m.elements(); ++e) {
        double& v = byRoot[static_cast<size_t>(uf.find(m.tets(0, e)))];
        v = std::max(v, 0.0) + m.volume(e) * m.fraction(e);
    }
    std::vector<double> volumes;
    for (double v : byRoot)
        if (v >= 0) volumes.push_back(v);
    std::sort(volumes.begin(), volumes.end(), std::greater<>());
    return volumes;
}

bool anyPartial(const Model& m) {
    for (Eigen::Index e = m.fraction.size() - 1; e >= 0; --e)
        if (m.fraction(e) < 1) return true;
    return false;
}

std::vector<std::uint8_t> partialNodes(const Model& m) {
    if (!anyPartial(m)) return {};
    std::vector<std::uint8_t> partial(static_cast<size_t>(m.nodes()), 1);
    std::vector<std::uint8_t> used(static_cast<size_t>(m.nodes()), 0);
    for (int e = 0; e < m.elements(); ++e)
        for (int a = 0; a < 4; ++a) {
            const auto i = static_cast<size_t>(m.tets(a, e));
            used[i] = 1;
            if (m.fraction(e) >= 1) partial[i] = 0;
        }
    for (size_t i = 0; i < used.size(); ++i) partial[i] &= used[i];
    return partial;
}

}  // namespace cutsim
