#include "geometry.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <tuple>

namespace cutsim::render {

using Vec3f = Eigen::Vector3f;
using Vec3d = Eigen::Vector3d;

void pushTriangle(std::vector<MeshVertex>& out, const Vec3d& a, const Vec3d& b, const Vec3d& c) {
    Vec3f n = (b - a).cross(c - a).normalized().cast<float>();
    for (const Vec3d* q : {&a, &b, &c}) {
        Vec3f p = q->cast<float>();
        out.push_back({{p.x(), p.y(), p.z()}, {n.x(), n.y(), n.z()}, 0, 0});
    }
}

// Tool solids as flat triangles in world coordinates.
void toolTriangles(const ToolShape& t, std::vector<MeshVertex>& out) {
    const Eigen::Matrix3d R = t.orientation.normalized().toRotationMatrix();
    auto world = [&](const Vec3d& p) { return Vec3d(t.position + R * p); };
    if (t.kind == ToolShape::Kind::Box) {
        const Vec3d h = t.size;
        auto corner = [&](int i) {
            return world(Vec3d((i & 1 ? 1 : -1) * h.x(), (i & 2 ? 1 : -1) * h.y(), (i & 4 ? 1 : -1) * h.z()));
        };
        // Each face as two triangles, counter-clockwise from outside.
        static constexpr int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                            {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
        for (const auto& f : faces) {
            pushTriangle(out, corner(f[0]), corner(f[1]), corner(f[2]));
            pushTriangle(out, corner(f[0]), corner(f[2]), corner(f[3]));
        }
        return;
    }
    // Sphere or capsule: a UV sphere whose two halves are pushed apart along local z.
    const double r = t.size.x();
    const double half = t.kind == ToolShape::Kind::Capsule ? t.size.y() : 0.0;
    constexpr int nu = 24, nv = 12;
    auto point = [&](int i, int j, double shift) {
        const double th = M_PI * j / nv, ph = 2 * M_PI * i / nu;
        return Vec3d(r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph), r * std::cos(th) + shift);
    };
    for (int j = 0; j < nv; ++j) {
        // Rows above the equator belong to the upper cap, the rest to the lower one; the row
        // across the equator becomes the cylinder.
        const double s0 = j < nv / 2 ? half : -half;
        const double s1 = j + 1 <= nv / 2 ? half : -half;
        for (int i = 0; i < nu; ++i) {
            Vec3d a = world(point(i, j, s0)), b = world(point(i + 1, j, s0));
            Vec3d c = world(point(i + 1, j + 1, s1)), d = world(point(i, j + 1, s1));
            // Each quad of the top row has a, b at the pole, of the bottom row c, d: keep the
            // triangle of three distinct points there, so the poles are closed.
            if (j + 1 < nv) pushTriangle(out, a, d, c);
            if (j > 0) pushTriangle(out, a, c, b);
        }
        if (j + 1 == nv / 2 && half > 0) {
            for (int i = 0; i < nu; ++i) {
                Vec3d a = world(point(i, nv / 2, half)), b = world(point(i + 1, nv / 2, half));
                Vec3d c = world(point(i + 1, nv / 2, -half)), d = world(point(i, nv / 2, -half));
                pushTriangle(out, a, d, c);
                pushTriangle(out, a, c, b);
            }
        }
    }
}

bool SurfaceTopology::update(const RenderSnapshot& snap) {
    const int n = snap.vertices(), nf = snap.faces();
    if (n == vertices && triangles.cols() == nf &&
        std::equal(triangles.data(), triangles.data() + triangles.size(), snap.triangles.data()))
        return false;
    triangles = snap.triangles;
    vertices = n;
    start.assign(static_cast<size_t>(n) + 1, 0);
    for (int f = 0; f < nf; ++f)
        for (int k = 0; k < 3; ++k) ++start[static_cast<size_t>(snap.triangles(k, f)) + 1];
    for (int v = 0; v < n; ++v) start[static_cast<size_t>(v) + 1] += start[static_cast<size_t>(v)];
    faces.resize(static_cast<size_t>(start.back()));
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (int f = 0; f < nf; ++f)
        for (int k = 0; k < 3; ++k) faces[static_cast<size_t>(fill[static_cast<size_t>(snap.triangles(k, f))]++)] = f;
    const std::vector<int> ids(triangles.data(), triangles.data() + triangles.size());
    halfEdges(ids, half);
    return true;
}

// The surface's triangle corners with their normals: given per vertex, or from the area-weighted
// normals of the faces around the vertex that meet this face at less than the crease angle, so
// box edges and cut rims stay sharp while curved surfaces shade smoothly.
void surfaceVertices(const RenderSnapshot& snap, const SurfaceTopology& topo, bool useMap,
                     std::vector<MeshVertex>& verts) {
    const int n = snap.vertices();
    const bool hasCut = snap.cutFace.size() == static_cast<size_t>(snap.faces());
    const bool given = snap.normals.cols() == n;
    const int nf = snap.faces();
    Eigen::Matrix3Xf faceN(3, given ? 0 : nf);
    if (!given)
        for (int f = 0; f < nf; ++f) {
            const auto t = snap.triangles.col(f);
            faceN.col(f) = (snap.positions.col(t[1]) - snap.positions.col(t[0]))
                               .cross(snap.positions.col(t[2]) - snap.positions.col(t[0]))
                               .cast<float>();
        }
    const std::vector<int>&start = topo.start, &vertexFaces = topo.faces;
    constexpr float kCosCrease = 0.64f;  // about 50 degrees
    verts.clear();
    verts.reserve(3 * static_cast<size_t>(nf));
    for (int f = 0; f < nf; ++f) {
        const float c = hasCut && snap.cutFace[static_cast<size_t>(f)] ? 1.0f : 0.0f;
        const Vec3f own = given ? Vec3f::Zero() : Vec3f(faceN.col(f).normalized());
        for (int k = 0; k < 3; ++k) {
            const int v = snap.triangles(k, f);
            Vec3f q;
            if (given) {
                q = snap.normals.col(v).cast<float>();
            } else {
                q.setZero();
                for (int i = start[static_cast<size_t>(v)]; i < start[static_cast<size_t>(v) + 1]; ++i) {
                    const auto other = faceN.col(vertexFaces[static_cast<size_t>(i)]);
                    if (own.dot(other) > kCosCrease * other.norm()) q += other;
                }
                q = q.squaredNorm() > 0 ? Vec3f(q.normalized()) : own;
            }
            const Vec3f p = snap.positions.col(v).cast<float>();
            verts.push_back({{p.x(), p.y(), p.z()}, {q.x(), q.y(), q.z()}, useMap ? float(snap.scalar[v]) : 0.0f, c});
        }
    }
}

void halfEdges(const std::vector<int>& ids, std::vector<std::pair<std::uint64_t, int>>& half) {
    const size_t nc = ids.size() - ids.size() % 3;
    half.clear();
    for (size_t c = 0; c < nc; ++c) {
        auto a = static_cast<std::uint32_t>(ids[c]), b = static_cast<std::uint32_t>(ids[c - c % 3 + (c + 1) % 3]);
        if (a > b) std::swap(a, b);
        half.emplace_back((std::uint64_t{a} << 32) | b, static_cast<int>(c));
    }
    std::sort(half.begin(), half.end());
}

// The silhouette of a triangle soup seen from `eye`: edges between a face turned towards the eye and
// one turned away, and open edges of a front face. Each segment carries the front face's corners,
// so a smoothed line along it blends the lit surface into what lies behind: edge anti-aliasing
// without multisampling. ids[c] names soup corner c's vertex; when its size differs from the
// soup's, corners at the same position are taken as one vertex.
void silhouetteLines(const std::vector<MeshVertex>& soup, std::vector<int>& ids, const Vec3f& eye,
                     std::vector<std::pair<std::uint64_t, int>>& half, std::vector<MeshVertex>& out) {
    const size_t nc = soup.size() - soup.size() % 3;
    auto pos = [&](size_t c) { return std::tie(soup[c].p[0], soup[c].p[1], soup[c].p[2]); };
    if (ids.size() != nc) {
        std::vector<int> order(nc);
        std::iota(order.begin(), order.end(), 0);
        std::sort(order.begin(), order.end(), [&](int a, int b) { return pos(size_t(a)) < pos(size_t(b)); });
        ids.resize(nc);
        int id = -1;
        for (size_t r = 0; r < nc; ++r) {
            if (r == 0 || pos(size_t(order[r])) != pos(size_t(order[r - 1]))) ++id;
            ids[size_t(order[r])] = id;
        }
    }
    halfEdges(ids, half);
    silhouetteLines(soup, half, eye, out);
}

void silhouetteLines(const std::vector<MeshVertex>& soup, const std::vector<std::pair<std::uint64_t, int>>& half,
                     const Vec3f& eye, std::vector<MeshVertex>& out) {
    auto corner = [&](size_t c) { return Vec3f(soup[c].p[0], soup[c].p[1], soup[c].p[2]); };
    auto front = [&](size_t f) {
        const Vec3f a = corner(3 * f);
        return (corner(3 * f + 1) - a).cross(corner(3 * f + 2) - a).dot(eye - a) > 0;
    };
    for (size_t i = 0, j = 0; i < half.size(); i = j) {
        int nFront = 0, seen = -1;
        for (j = i; j < half.size() && half[j].first == half[i].first; ++j)
            if (front(size_t(half[j].second) / 3)) {
                ++nFront;
                seen = half[j].second;
            }
        if (nFront == 0 || (nFront == static_cast<int>(j - i) && j - i > 1)) continue;
        const auto c = static_cast<size_t>(seen);
        out.push_back(soup[c]);
        out.push_back(soup[c - c % 3 + (c + 1) % 3]);
    }
}

// Segments (corner pairs) as screen-space quads `halfWidth` + 1/2 px to each side of the line (where
// the shader's 1 px ramp ends: a wider quad only adds fragments of no coverage): each
// corner keeps its world position and gets an offset in normalised device coordinates, and `edge`,
// the distance from the centre line, which the fragment shader turns into coverage. A segment is
// clipped to the front of the camera. width, height: half the frame's size [px].
void segmentQuads(const std::vector<MeshVertex>& segs, const Eigen::Matrix4f& pv, float width, float height,
                  float halfWidth, std::vector<MeshVertex>& out) {
    constexpr float kNearW = 1e-5f;
    const float reach = halfWidth + 0.5f;
    for (size_t i = 0; i + 1 < segs.size(); i += 2) {
        MeshVertex e[2] = {segs[i], segs[i + 1]};
        Eigen::Vector4f c[2];
        for (int k = 0; k < 2; ++k) c[k] = pv * Eigen::Vector4f(e[k].p[0], e[k].p[1], e[k].p[2], 1);
        if (c[0].w() < kNearW && c[1].w() < kNearW) continue;
        for (int k = 0; k < 2; ++k) {
            if (c[k].w() >= kNearW) continue;
            // Clip and world coordinates are affine in each other: move both by the same fraction.
            const float t = (kNearW - c[k].w()) / (c[1 - k].w() - c[k].w());
            c[k] += t * (c[1 - k] - c[k]);
            for (int a = 0; a < 3; ++a) e[k].p[a] += t * (e[1 - k].p[a] - e[k].p[a]);
        }
        const Eigen::Vector2f s0(c[0].x() / c[0].w() * width, c[0].y() / c[0].w() * height);
        const Eigen::Vector2f s1(c[1].x() / c[1].w() * width, c[1].y() / c[1].w() * height);
        Eigen::Vector2f d = s1 - s0;
        d = d.squaredNorm() > 0 ? Eigen::Vector2f(d.normalized()) : Eigen::Vector2f::UnitX();
        const Eigen::Vector2f n(-d.y(), d.x());
        MeshVertex q[4];
        for (int k = 0; k < 4; ++k) {
            const float side = k % 2 ? -1.0f : 1.0f;
            q[k] = e[k / 2];
            q[k].off[0] = side * reach * n.x() / width;  // a pixel is 1 / (half size) in NDC
            q[k].off[1] = side * reach * n.y() / height;
            q[k].edge = side * reach;
        }
        for (int k : {0, 1, 2, 2, 1, 3}) out.push_back(q[k]);
    }
}

// Tets given by their corners: faces and edges.
void tetGeometry(const Eigen::Matrix3Xd& corners, std::vector<MeshVertex>& tris, std::vector<float>& lines) {
    static constexpr int faces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    static constexpr int edges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
    const int nCrit = static_cast<int>(corners.cols() / 4);
    for (int e = 0; e < nCrit; ++e) {
        auto c = [&](int a) { return Vec3d(corners.col(4 * e + a)); };
        for (const auto& f : faces) pushTriangle(tris, c(f[0]), c(f[1]), c(f[2]));
        for (const auto& ed : edges)
            for (int a : {ed[0], ed[1]}) {
                Vec3f p = c(a).cast<float>();
                lines.insert(lines.end(), {p.x(), p.y(), p.z()});
            }
    }
}

}  // namespace cutsim::render
