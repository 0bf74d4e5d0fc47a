// The improver's assembled rows (rows.hpp).
#include "improve/rows.hpp"

#include <cmath>

namespace cutsim {

void KeptRows::resize(int nodes) {
    nbr.assign(nodes, {});
    blk.assign(nodes, {});
    vs.assign(nodes, 0.0);
}

int KeptRows::slotOf(int i, int j) {
    auto& nb = nbr[i];
    for (size_t k = 0; k < nb.size(); ++k)
        if (nb[k] == j) return static_cast<int>(k);
    nb.push_back(j);
    blk[i].push_back(Eigen::Matrix3d::Zero());
    return static_cast<int>(nb.size()) - 1;
}

void KeptRows::scatter(const Tet& t, const Mat34& g, double V, const Slots& slot) {
    for (int a = 0; a < 4; ++a) {
        vs[t[a]] += V;
        const Eigen::Vector3d la = V * lame * g.col(a), ma = V * mu * g.col(a);
        double* row = blk[t[a]].front().data();
        for (int b = 0; b < 4; ++b) {
            const Eigen::Vector3d gb = g.col(b);
            const double d = ma.dot(gb);
            double* K = row + 9 * slot[4 * a + b];  // column-major
            for (int c = 0; c < 3; ++c)
                for (int r = 0; r < 3; ++r) K[3 * c + r] += la[r] * gb[c] + gb[r] * ma[c] + (r == c ? d : 0.0);
        }
    }
}

void KeptRows::rescatter(const Tet& t, const Mat34& g0, double v0, const Mat34& g1, double v1, const Slots& slot) {
    // K_ba = K_ab^T: the upper blocks are computed, each written to both places.
    for (int a = 0; a < 4; ++a) {
        vs[t[a]] += v1 - v0;
        const Eigen::Vector3d la0 = -v0 * lame * g0.col(a), ma0 = -v0 * mu * g0.col(a);
        const Eigen::Vector3d la1 = v1 * lame * g1.col(a), ma1 = v1 * mu * g1.col(a);
        for (int b = a; b < 4; ++b) {
            const Eigen::Vector3d gb0 = g0.col(b), gb1 = g1.col(b);
            const double d = ma0.dot(gb0) + ma1.dot(gb1);
            double* K = blk[t[a]][slot[4 * a + b]].data();  // column-major
            double* L = blk[t[b]][slot[4 * b + a]].data();
            for (int c = 0; c < 3; ++c)
                for (int r = 0; r < 3; ++r) {
                    const double k =
                        (la0[r] * gb0[c] + gb0[r] * ma0[c]) + (la1[r] * gb1[c] + gb1[r] * ma1[c]) + (r == c ? d : 0.0);
                    K[3 * c + r] += k;
                    if (b != a) L[3 * r + c] += k;
                }
        }
    }
}

void KeptRows::scaled(const std::vector<std::vector<int>>& nt, const std::vector<Tet>& T, double rq,
                      ScaledStiffness& op) const {
    const int n = static_cast<int>(nbr.size());
    std::vector<int> compact(n, -1), mark(n, -1);
    std::vector<double> s(n, 0.0);
    int nf = 0;
    for (int i = 0; i < n; ++i)
        if (!nt[i].empty()) {
            compact[i] = nf++;
            s[i] = 1 / std::sqrt(rq * vs[i]);
        }
    size_t blocks = 0;
    for (int i = 0; i < n; ++i) blocks += nbr[i].size();
    op.rowStart.assign(1, 0);
    op.rowStart.reserve(nf + 1);
    op.col.clear();
    op.col.reserve(blocks);
    op.val.clear();
    op.val.reserve(9 * blocks);
    for (int i = 0; i < n; ++i) {
        if (compact[i] < 0) continue;
        // A flip or collapse leaves couplings without elements (their blocks round-off): left out.
        for (int e : nt[i])
            for (int j : T[e]) mark[j] = i;
        for (size_t k = 0; k < nbr[i].size(); ++k) {
            const int j = nbr[i][k];
            if (mark[j] != i) continue;
            op.col.push_back(compact[j]);
            const double sij = s[i] * s[j];
            const double* K = blk[i][k].data();
            for (int q = 0; q < 9; ++q) op.val.push_back(sij * K[q]);
        }
        op.rowStart.push_back(static_cast<int>(op.col.size()));
    }
}

}  // namespace cutsim
