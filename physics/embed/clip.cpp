#include "embed/clip.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>

namespace cutsim {

namespace {

struct ClipVertex {
    Eigen::Vector3d x;
    Eigen::Vector4d l;  // barycentric coordinates in the tet
};

// Sutherland-Hodgman against l_i >= 0; n in, returns n out (arrays hold up to 16 vertices).
int clipPlane(const ClipVertex* in, int n, int i, ClipVertex* out) {
    int m = 0;
    for (int k = 0; k < n; ++k) {
        const ClipVertex& a = in[k];
        const ClipVertex& b = in[(k + 1) % n];
        const bool ina = a.l[i] >= 0, inb = b.l[i] >= 0;
        if (ina) out[m++] = a;
        if (ina != inb) {
            const double s = a.l[i] / (a.l[i] - b.l[i]);
            out[m].x = a.x + s * (b.x - a.x);
            out[m].l = a.l + s * (b.l - a.l);
            out[m].l[i] = 0;
            ++m;
        }
    }
    return m;
}

// Does segment a-b cross triangle (t0, t1, t2)? If so, s is the crossing's parameter on a-b and
// dir is +1 when the triangle normal points along b - a.
bool segmentCrossesTriangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& t0,
                            const Eigen::Vector3d& t1, const Eigen::Vector3d& t2, double& s, int& dir) {
    const Eigen::Vector3d n = (t1 - t0).cross(t2 - t0);
    const double da = n.dot(a - t0), db = n.dot(b - t0);
    if ((da >= 0) == (db >= 0)) return false;
    s = da / (da - db);
    const Eigen::Vector3d x = a + s * (b - a);
    const double e0 = n.dot((t1 - t0).cross(x - t0)), e1 = n.dot((t2 - t1).cross(x - t1)),
                 e2 = n.dot((t0 - t2).cross(x - t2));
    if (e0 < 0 || e1 < 0 || e2 < 0) return false;
    dir = db > da ? 1 : -1;
    return true;
}

bool boxesOverlap(const Eigen::Vector3d& lo1, const Eigen::Vector3d& hi1, const Eigen::Vector3d& lo2,
                  const Eigen::Vector3d& hi2) {
    return (lo1.array() <= hi2.array()).all() && (lo2.array() <= hi1.array()).all();
}

}  // namespace

double tetInsideFraction(const SurfaceMesh& s, const std::vector<int>& tris, const Eigen::Vector3d& p0,
                         const Eigen::Vector3d& p1, const Eigen::Vector3d& p2, const Eigen::Vector3d& p3,
                         bool p3Inside) {
    Eigen::Matrix3d Dm;
    Dm << p1 - p0, p2 - p0, p3 - p0;
    const double V = Dm.determinant() / 6.0;
    const Eigen::Matrix3d B = Dm.inverse();
    auto bary = [&](const Eigen::Vector3d& x) {
        const Eigen::Vector3d w = B * (x - p0);
        return Eigen::Vector4d(1.0 - w.sum(), w[0], w[1], w[2]);
    };
    const Eigen::Vector3d nF = (p2 - p1).cross(p3 - p1);  // outward normal of F0 (away from p0), |nF| = 2 area
    const double nF2 = nF.squaredNorm();

    double cone = 0, seg = 0, pt = 0;
    ClipVertex bufA[16], bufB[16];
    for (int f : tris) {
        const Eigen::Vector3d t[3] = {s.V.col(s.F(0, f)), s.V.col(s.F(1, f)), s.V.col(s.F(2, f))};
        // 3D: the triangle clipped to the tet, as cones from p0 (fan of the clipped polygon).
        int n = 3;
        for (int k = 0; k < 3; ++k) bufA[k] = {t[k], bary(t[k])};
        ClipVertex* in = bufA;
        ClipVertex* out = bufB;
        for (int i = 0; i < 4 && n > 0; ++i) {
            n = clipPlane(in, n, i, out);
            std::swap(in, out);
        }
        for (int k = 1; k + 1 < n; ++k) cone += tetSignedVolume(p0, in[0].x, in[k].x, in[k + 1].x);

        // 2D: the triangle's trace on the plane of F0 (l0 = 0), clipped to F0, oriented
        // counter-clockwise about nF for the region inside the surface.
        const Eigen::Vector4d l[3] = {bary(t[0]), bary(t[1]), bary(t[2])};
        Eigen::Vector3d sp[2];
        Eigen::Vector4d sl[2];
        int ns = 0;
        for (int k = 0; k < 3 && ns < 2; ++k) {
            const int k1 = (k + 1) % 3;
            if ((l[k][0] >= 0) != (l[k1][0] >= 0)) {
                const double u = l[k][0] / (l[k][0] - l[k1][0]);
                sp[ns] = t[k] + u * (t[k1] - t[k]);
                sl[ns] = l[k] + u * (l[k1] - l[k]);
                ++ns;
            }
        }
        if (ns == 2) {
            double u0 = 0, u1 = 1;
            for (int i = 1; i < 4; ++i) {
                const double a = sl[0][i], b = sl[1][i];
                if (a < 0 && b < 0) {
                    u0 = 1;
                    u1 = 0;
                    break;
                }
                if (a < 0)
                    u0 = std::max(u0, a / (a - b));
                else if (b < 0)
                    u1 = std::min(u1, a / (a - b));
            }
            if (u1 > u0) {
                Eigen::Vector3d a = sp[0] + u0 * (sp[1] - sp[0]), b = sp[0] + u1 * (sp[1] - sp[0]);
                const Eigen::Vector3d nt = (t[1] - t[0]).cross(t[2] - t[0]);
                if ((b - a).dot(nF.cross(nt)) < 0) std::swap(a, b);
                seg += nF.dot((a - p1).cross(b - p1)) / nF2;
            }
        }

        // 1D: where the triangle crosses E = p2 -> p3.
        double u = 0;
        int dir = 0;
        if (segmentCrossesTriangle(p2, p3, t[0], t[1], t[2], u, dir)) pt += dir * u;
    }
    return cone / V + seg + pt + (p3Inside ? 1.0 : 0.0);
}

bool insideFromAnchor(const SurfaceMesh& s, const std::vector<int>& tris, const Eigen::Vector3d& a, bool aInside,
                      const Eigen::Vector3d& x) {
    bool in = aInside;
    double u = 0;
    int dir = 0;
    for (int f : tris)
        if (segmentCrossesTriangle(a, x, s.V.col(s.F(0, f)), s.V.col(s.F(1, f)), s.V.col(s.F(2, f)), u, dir)) in = !in;
    return in;
}

namespace {

struct RefineContext {
    const SurfaceMesh& s;
    int levels;
    const std::function<bool(const Eigen::Vector3d&)>& inside;
    std::vector<double>& acc;  // volume share per level
};

void refine(RefineContext& c, const std::vector<int>& tris, const Eigen::Vector3d (&p)[4], const bool (&in)[4],
            int depth, double share) {
    // Triangles whose box touches this child.
    Eigen::Vector3d lo = p[0], hi = p[0];
    for (int k = 1; k < 4; ++k) {
        lo = lo.cwiseMin(p[k]);
        hi = hi.cwiseMax(p[k]);
    }
    std::vector<int> near;
    for (int f : tris) {
        const Eigen::Vector3d a = c.s.V.col(c.s.F(0, f)), b = c.s.V.col(c.s.F(1, f)), d = c.s.V.col(c.s.F(2, f));
        if (boxesOverlap(lo, hi, a.cwiseMin(b).cwiseMin(d), a.cwiseMax(b).cwiseMax(d))) near.push_back(f);
    }
    if (near.empty()) {
        // Untouched: one label for the whole child, at this level and every finer one.
        if (in[0])
            for (int l = depth; l <= c.levels; ++l) c.acc[l] += share;
        return;
    }
    // This level's estimate counts the child by its centroid.
    if (c.inside(0.25 * (p[0] + p[1] + p[2] + p[3]))) c.acc[depth] += share;
    if (depth == c.levels) return;
    // Red refinement: corners 0..3, midpoints 4..9 of edges 01 02 03 12 13 23; the inner
    // octahedron is split along the diagonal 5-8 (midpoints of 02 and 13).
    static constexpr int edge[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
    static constexpr int child[8][4] = {{0, 4, 5, 6}, {4, 1, 7, 8}, {5, 7, 2, 9}, {6, 8, 9, 3},
                                        {4, 5, 6, 8}, {4, 5, 7, 8}, {5, 6, 8, 9}, {5, 7, 8, 9}};
    Eigen::Vector3d q[10];
    bool qin[10];
    for (int k = 0; k < 4; ++k) {
        q[k] = p[k];
        qin[k] = in[k];
    }
    for (int e = 0; e < 6; ++e) {
        q[4 + e] = 0.5 * (p[edge[e][0]] + p[edge[e][1]]);
        qin[4 + e] = c.inside(q[4 + e]);
    }
    for (const auto& ch : child) {
        const Eigen::Vector3d cp[4] = {q[ch[0]], q[ch[1]], q[ch[2]], q[ch[3]]};
        const bool cin[4] = {qin[ch[0]], qin[ch[1]], qin[ch[2]], qin[ch[3]]};
        refine(c, near, cp, cin, depth + 1, share / 8);
    }
}

}  // namespace

void refinedInsideFraction(const SurfaceMesh& s, const std::vector<int>& tris, const Eigen::Vector3d (&p)[4],
                           const bool (&cornerInside)[4], int levels,
                           const std::function<bool(const Eigen::Vector3d&)>& inside,
                           std::vector<double>& fractionAtLevel) {
    fractionAtLevel.assign(static_cast<size_t>(levels) + 1, 0.0);
    RefineContext c{s, levels, inside, fractionAtLevel};
    refine(c, tris, p, cornerInside, 0, 1.0);
}

Eigen::Vector3d closestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                       const Eigen::Vector3d& c) {
    const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
    const double d1 = ab.dot(ap), d2 = ac.dot(ap);
    if (d1 <= 0 && d2 <= 0) return a;
    const Eigen::Vector3d bp = p - b;
    const double d3 = ab.dot(bp), d4 = ac.dot(bp);
    if (d3 >= 0 && d4 <= d3) return b;
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
    const Eigen::Vector3d cp = p - c;
    const double d5 = ab.dot(cp), d6 = ac.dot(cp);
    if (d6 >= 0 && d5 <= d6) return c;
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
    const double den = 1.0 / (va + vb + vc);
    return a + ab * (vb * den) + ac * (vc * den);
}

double pointTriangleDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                             const Eigen::Vector3d& c) {
    return (p - closestPointOnTriangle(p, a, b, c)).norm();
}

}  // namespace cutsim
