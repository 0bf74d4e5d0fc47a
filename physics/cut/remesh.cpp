#include "cut/remesh.hpp"

#include "mesh/generate.hpp"

#ifdef CUTSIM_HAVE_TETGEN
#include <tetgen.h>
#endif

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <sstream>
#include <utility>
#include <vector>

#include <sys/wait.h>
#include <unistd.h>

namespace cutsim {

bool haveTetGen() {
#ifdef CUTSIM_HAVE_TETGEN
    return true;
#else
    return false;
#endif
}

#ifdef CUTSIM_HAVE_TETGEN
namespace {

// A closed surface as TetGen facets: coplanar edge-connected triangles become one polygon (their
// boundary loop) so the cut face is one facet and TetGen is free to triangulate it well.
struct Plc {
    std::vector<Eigen::Vector3d> points;
    std::vector<std::vector<std::vector<int>>> facets;  // facet -> polygons -> point indices
};

Plc buildPlc(const TetMesh& piece, const Eigen::Matrix3Xi& F, double coplanarTol) {
    Plc plc;
    // Compact the surface's vertices.
    std::map<int, int> vid;
    for (Eigen::Index f = 0; f < F.cols(); ++f)
        for (int k = 0; k < 3; ++k) vid.try_emplace(F(k, f), 0);
    for (auto& [v, id] : vid) {
        id = static_cast<int>(plc.points.size());
        plc.points.push_back(piece.X.col(v));
    }
    const int nf = static_cast<int>(F.cols());
    std::vector<std::array<int, 3>> tri(static_cast<size_t>(nf));
    std::vector<Eigen::Vector3d> nrm(static_cast<size_t>(nf));
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (const auto& p : plc.points) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    const double tol = coplanarTol * (hi - lo).norm();
    for (int f = 0; f < nf; ++f) {
        tri[f] = {vid[F(0, f)], vid[F(1, f)], vid[F(2, f)]};
        const auto& P = plc.points;
        nrm[f] = (P[tri[f][1]] - P[tri[f][0]]).cross(P[tri[f][2]] - P[tri[f][0]]).normalized();
    }
    // Directed edge -> face; the reverse edge finds the neighbour across it.
    std::map<std::pair<int, int>, int> edgeFace;
    for (int f = 0; f < nf; ++f)
        for (int k = 0; k < 3; ++k) edgeFace[{tri[f][k], tri[f][(k + 1) % 3]}] = f;

    std::vector<int> group(static_cast<size_t>(nf), -1);
    for (int seed = 0; seed < nf; ++seed) {
        if (group[seed] >= 0) continue;
        const int g = seed;
        const Eigen::Vector3d n0 = nrm[seed], x0 = plc.points[tri[seed][0]];
        std::vector<int> members{seed}, stack{seed};
        group[seed] = g;
        while (!stack.empty()) {
            const int f = stack.back();
            stack.pop_back();
            for (int k = 0; k < 3; ++k) {
                auto it = edgeFace.find({tri[f][(k + 1) % 3], tri[f][k]});
                if (it == edgeFace.end() || group[it->second] >= 0) continue;
                const int h = it->second;
                bool coplanar = nrm[h].dot(n0) > 1 - 1e-9;
                for (int j = 0; j < 3 && coplanar; ++j) coplanar = std::abs(n0.dot(plc.points[tri[h][j]] - x0)) <= tol;
                if (!coplanar) continue;
                group[h] = g;
                members.push_back(h);
                stack.push_back(h);
            }
        }
        // Boundary loop of the group: directed edges whose reverse is not in the group.
        std::map<int, int> next;
        bool simple = true;
        for (const int f : members)
            for (int k = 0; k < 3; ++k) {
                const int a = tri[f][k], b = tri[f][(k + 1) % 3];
                auto it = edgeFace.find({b, a});
                if (it != edgeFace.end() && group[it->second] == g) continue;
                simple = simple && next.emplace(a, b).second;  // a pinch vertex: keep the triangles
            }
        std::vector<int> loop;
        if (simple && !next.empty()) {
            int v = next.begin()->first;
            do {
                loop.push_back(v);
                v = next[v];
            } while (v != loop.front() && loop.size() <= next.size());
            simple = loop.size() == next.size();  // one loop covers every boundary edge
        }
        std::vector<std::vector<int>> polys;
        if (simple && !loop.empty()) {
            polys.push_back(loop);
        } else {
            for (const int f : members) polys.push_back({tri[f][0], tri[f][1], tri[f][2]});
        }
        plc.facets.push_back(std::move(polys));
    }

    // A loop vertex on a straight edge between exactly two polygon facets (a cut point on a box
    // edge, a grid node on a flat face's border) is dropped from both: TetGen places its own
    // points there, and nearly collinear input vertices would make needle-thin input features.
    const int np = static_cast<int>(plc.points.size());
    std::vector<int> uses(static_cast<size_t>(np), 0);
    std::vector<char> straight(static_cast<size_t>(np), 1);
    for (const auto& polys : plc.facets) {
        const bool isLoop = polys.size() == 1 && polys[0].size() > 3;
        for (const auto& poly : polys) {
            const size_t m = poly.size();
            for (size_t k = 0; k < m; ++k) {
                const int v = poly[k];
                ++uses[v];
                const Eigen::Vector3d a = plc.points[poly[(k + m - 1) % m]], b = plc.points[v],
                                      c = plc.points[(poly[(k + 1) % m])];
                const bool line = (b - a).cross(c - b).norm() <= tol * (c - a).norm() && (b - a).dot(c - b) > 0;
                straight[v] = straight[v] && isLoop && line;
            }
        }
    }
    for (auto& polys : plc.facets) {
        if (polys.size() != 1) continue;
        std::vector<int> kept;
        for (const int v : polys[0])
            if (!(straight[v] && uses[v] == 2)) kept.push_back(v);
        if (kept.size() >= 3) polys[0] = std::move(kept);
    }
    // Only referenced points reach TetGen (it would insert every listed point).
    std::vector<int> newIndex(static_cast<size_t>(np), -1);
    std::vector<Eigen::Vector3d> used;
    for (auto& polys : plc.facets)
        for (auto& poly : polys)
            for (int& v : poly) {
                if (newIndex[v] < 0) {
                    newIndex[v] = static_cast<int>(used.size());
                    used.push_back(plc.points[v]);
                }
                v = newIndex[v];
            }
    plc.points = std::move(used);
    return plc;
}

bool writeAll(int fd, const void* data, size_t bytes) {
    const char* p = static_cast<const char*>(data);
    while (bytes > 0) {
        const ssize_t n = ::write(fd, p, bytes);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return false;
        p += n, bytes -= static_cast<size_t>(n);
    }
    return true;
}

std::string tetgenReason(int code) {
    switch (code) {
    case 1: return "out of memory";
    case 2: return "internal error";
    case 3: return "the surface intersects itself";
    case 4: return "an input feature is too small for its tolerance";
    case 5: return "two input facets are too close";
    case 10: return "the input is invalid";
    default: return "error code " + std::to_string(code);
    }
}

// Runs TetGen on `in` in a child process and appends its mesh to (X, T).
void runTetgen(tetgenio& in, const std::string& switches, const std::string& what, std::vector<Eigen::Vector3d>& X,
               std::vector<Eigen::Vector4i>& T);

// Runs TetGen on one PLC and appends the tets to (X, T).
void tetrahedralizePlc(const Plc& plc, const std::string& switches, const std::string& what,
                       std::vector<Eigen::Vector3d>& X, std::vector<Eigen::Vector4i>& T) {
    tetgenio in;
    in.firstnumber = 0;
    in.numberofpoints = static_cast<int>(plc.points.size());
    in.pointlist = new REAL[3 * plc.points.size()];
    for (size_t i = 0; i < plc.points.size(); ++i)
        for (int k = 0; k < 3; ++k) in.pointlist[3 * i + k] = plc.points[i][k];
    in.numberoffacets = static_cast<int>(plc.facets.size());
    in.facetlist = new tetgenio::facet[plc.facets.size()];
    for (size_t f = 0; f < plc.facets.size(); ++f) {
        tetgenio::facet& fc = in.facetlist[f];
        tetgenio::init(&fc);
        fc.numberofpolygons = static_cast<int>(plc.facets[f].size());
        fc.polygonlist = new tetgenio::polygon[plc.facets[f].size()];
        for (size_t p = 0; p < plc.facets[f].size(); ++p) {
            tetgenio::polygon& pg = fc.polygonlist[p];
            tetgenio::init(&pg);
            const auto& poly = plc.facets[f][p];
            pg.numberofvertices = static_cast<int>(poly.size());
            pg.vertexlist = new int[poly.size()];
            std::copy(poly.begin(), poly.end(), pg.vertexlist);
        }
    }
    runTetgen(in, switches, what, X, T);
}

void runTetgen(tetgenio& in, const std::string& switches, const std::string& what, std::vector<Eigen::Vector3d>& X,
               std::vector<Eigen::Vector4i>& T) {
    tetgenio out;
    std::vector<char> sw(switches.begin(), switches.end());
    sw.push_back('\0');
    // TetGen 1.5 frees its mesh twice when it throws (terminatetetgen, then the destructor), so an
    // error would crash this process: run it in a child and read the mesh back through a pipe.
    int fd[2];
    if (::pipe(fd) != 0) throw RemeshError("remesh: cannot create a pipe for TetGen");
    std::fflush(nullptr);
    const pid_t pid = ::fork();
    if (pid < 0) {
        ::close(fd[0]), ::close(fd[1]);
        throw RemeshError("remesh: cannot start TetGen (fork failed)");
    }
    if (pid == 0) {
        ::close(fd[0]);
        int code = 0;
        try {
            tetrahedralize(sw.data(), &in, &out);
        } catch (int c) {
            code = c;
        }
        const int head[3] = {code, out.numberofpoints,
                             code == 0 && out.numberofcorners == 4 ? out.numberoftetrahedra : 0};
        bool ok = writeAll(fd[1], head, sizeof head);
        if (code == 0) {
            ok = ok && writeAll(fd[1], out.pointlist, sizeof(REAL) * 3 * static_cast<size_t>(head[1]));
            for (int t = 0; t < head[2] && ok; ++t) {
                int tt[4];
                for (int k = 0; k < 4; ++k) tt[k] = out.tetrahedronlist[4 * t + k] - out.firstnumber;
                ok = writeAll(fd[1], tt, sizeof tt);
            }
        }
        ::_exit(ok ? 0 : 1);
    }
    ::close(fd[1]);
    std::vector<char> buf;
    char chunk[65536];
    for (;;) {
        const ssize_t n = ::read(fd[0], chunk, sizeof chunk);
        if (n > 0)
            buf.insert(buf.end(), chunk, chunk + n);
        else if (n == 0 || errno != EINTR)
            break;
    }
    ::close(fd[0]);
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {}
    int head[3] = {0, 0, 0};
    if (buf.size() < sizeof head) {
        throw RemeshError("TetGen could not mesh " + what + ": it stopped on an error" +
                          (WIFSIGNALED(status) ? " (signal " + std::to_string(WTERMSIG(status)) + ")" : std::string()) +
                          "; TetGen 1.5 crashes while reporting bad input such as a self-intersecting surface"
                          " (switches -" +
                          switches + ")");
    }
    std::memcpy(head, buf.data(), sizeof head);
    if (head[0] != 0)
        throw RemeshError("TetGen rejected " + what + ": " + tetgenReason(head[0]) + " (switches -" + switches + ")");
    if (head[2] <= 0 || buf.size() != sizeof head + sizeof(double) * 3 * static_cast<size_t>(head[1]) +
                                          sizeof(int) * 4 * static_cast<size_t>(head[2]))
        throw RemeshError("TetGen produced no tets for " + what + " (switches -" + switches + ")");
    const char* pts = buf.data() + sizeof head;
    const char* tts = pts + sizeof(double) * 3 * static_cast<size_t>(head[1]);
    const int base = static_cast<int>(X.size());
    for (int i = 0; i < head[1]; ++i) {
        double p[3];
        std::memcpy(p, pts + sizeof p * static_cast<size_t>(i), sizeof p);
        X.emplace_back(p[0], p[1], p[2]);
    }
    for (int t = 0; t < head[2]; ++t) {
        int q[4];
        std::memcpy(q, tts + sizeof q * static_cast<size_t>(t), sizeof q);
        Eigen::Vector4i tt(base + q[0], base + q[1], base + q[2], base + q[3]);
        if (tetSignedVolume(X[tt[0]], X[tt[1]], X[tt[2]], X[tt[3]]) < 0) std::swap(tt[2], tt[3]);
        T.push_back(tt);
    }
}

}  // namespace

namespace {
TetMesh meshOf(const std::vector<Eigen::Vector3d>& X, const std::vector<Eigen::Vector4i>& T,
               const std::string& source) {
    TetMesh out;
    out.X.resize(3, static_cast<Eigen::Index>(X.size()));
    for (size_t i = 0; i < X.size(); ++i) out.X.col(static_cast<Eigen::Index>(i)) = X[i];
    out.tets.resize(4, static_cast<Eigen::Index>(T.size()));
    for (size_t t = 0; t < T.size(); ++t) out.tets.col(static_cast<Eigen::Index>(t)) = T[t];
    out.source = source;
    return out;
}
}  // namespace

TetMesh tetgenOptimize(const TetMesh& mesh, const std::string& switches) {
    tetgenio in;
    in.firstnumber = 0;
    in.numberofpoints = mesh.nodes();
    in.pointlist = new REAL[3 * static_cast<size_t>(mesh.nodes())];
    std::copy(mesh.X.data(), mesh.X.data() + 3 * mesh.nodes(), in.pointlist);
    in.numberofcorners = 4;
    in.numberoftetrahedra = mesh.elements();
    in.tetrahedronlist = new int[4 * static_cast<size_t>(mesh.elements())];
    std::copy(mesh.tets.data(), mesh.tets.data() + 4 * mesh.elements(), in.tetrahedronlist);
    std::vector<Eigen::Vector3d> X;
    std::vector<Eigen::Vector4i> T;
    runTetgen(in, switches, mesh.source.empty() ? std::string("a tet mesh") : mesh.source, X, T);
    return meshOf(X, T, mesh.source);
}

TetMesh tetgenSurface(const SurfaceMesh& s, const std::string& switches) {
    Plc plc;
    for (int v = 0; v < s.vertices(); ++v) plc.points.push_back(s.V.col(v));
    plc.facets.resize(static_cast<size_t>(s.faces()));
    for (int f = 0; f < s.faces(); ++f) plc.facets[static_cast<size_t>(f)] = {{s.F(0, f), s.F(1, f), s.F(2, f)}};
    std::vector<Eigen::Vector3d> X;
    std::vector<Eigen::Vector4i> T;
    tetrahedralizePlc(plc, switches, s.source.empty() ? std::string("a surface") : s.source, X, T);
    return meshOf(X, T, s.source);
}
#else
TetMesh tetgenOptimize(const TetMesh&, const std::string&) {
    throw RemeshError("TetGen's optimisation needs TetGen (Debian libtet1.5-dev); this build has none");
}
TetMesh tetgenSurface(const SurfaceMesh&, const std::string&) {
    throw RemeshError("tetrahedralising a surface needs TetGen (Debian libtet1.5-dev); this build has none");
}
#endif

RemeshResult remeshPieces(const TetMesh& mesh, const RemeshOptions& opts) {
#ifndef CUTSIM_HAVE_TETGEN
    (void)mesh, (void)opts;
    throw RemeshError("remeshing needs TetGen (Debian libtet1.5-dev); this build has none");
#else
    RemeshResult res;
    RemeshReport& rep = res.report;
    if (mesh.elements() == 0) throw RemeshError("remesh: " + mesh.source + " has no tets");
    rep.volumeBefore = totalVolume(mesh);
    double maxVolume = opts.maxVolume > 0 ? opts.maxVolume : rep.volumeBefore / mesh.elements();
    // TetGen reads the bound as plain digits: fixed notation with ~9 significant digits.
    std::ostringstream sw;
    sw.setf(std::ios::fixed);
    sw.precision(std::clamp(9 - static_cast<int>(std::floor(std::log10(maxVolume))), 9, 40));
    sw << opts.switches << "zQa" << maxVolume;
    rep.switches = sw.str();

    std::vector<int> piece;
    rep.pieces = connectedPieces(mesh, &piece);
    std::vector<std::vector<int>> members(static_cast<size_t>(rep.pieces));
    for (int e = 0; e < mesh.elements(); ++e) members[piece[e]].push_back(e);

    std::vector<Eigen::Vector3d> X;
    std::vector<Eigen::Vector4i> T;
    for (int p = 0; p < rep.pieces; ++p) {
        TetMesh sub;
        sub.X = mesh.X;  // unused nodes are harmless: buildPlc keeps only surface vertices
        sub.tets.resize(4, static_cast<Eigen::Index>(members[p].size()));
        for (size_t k = 0; k < members[p].size(); ++k)
            sub.tets.col(static_cast<Eigen::Index>(k)) = mesh.tets.col(members[p][k]);
        const Eigen::Matrix3Xi F = boundaryFaces(sub);
        const Plc plc = buildPlc(sub, F, opts.coplanarTolerance);
        rep.surfaceTriangles += static_cast<int>(F.cols());
        rep.facets += static_cast<int>(plc.facets.size());
        tetrahedralizePlc(plc, rep.switches, "piece " + std::to_string(p) + " of " + mesh.source, X, T);
    }

    TetMesh& m = res.mesh;
    m.source = mesh.source;
    m.X.resize(3, static_cast<Eigen::Index>(X.size()));
    for (size_t i = 0; i < X.size(); ++i) m.X.col(static_cast<Eigen::Index>(i)) = X[i];
    m.tets.resize(4, static_cast<Eigen::Index>(T.size()));
    for (size_t t = 0; t < T.size(); ++t) m.tets.col(static_cast<Eigen::Index>(t)) = T[t];
    m = spatialOrder(m);  // TetGen's order is arbitrary: threads would share most nodes
    rep.nodes = m.nodes();
    rep.tets = m.elements();
    rep.minVolume = std::numeric_limits<double>::infinity();
    for (int e = 0; e < m.elements(); ++e) rep.minVolume = std::min(rep.minVolume, tetSignedVolume(m, e));
    rep.volumeAfter = totalVolume(m);
    if (!(rep.minVolume > 0))
        throw RemeshError("TetGen produced a zero-volume tet for " + mesh.source + " (switches -" + rep.switches + ")");
    return res;
#endif
}

RemeshResult remeshCut(const TetMesh& mesh, const CutPlane& plane, const RemeshOptions& opts) {
    ConformingOptions co;
    co.snapFraction = 0;  // exact surface; the split's slivers never reach the new mesh
    co.keep = opts.keep;
    const ConformingResult cut = conformingCut(mesh, plane, co);
    RemeshOptions ro = opts;
    // The resolution follows the uncut input, not the split tets.
    if (ro.maxVolume <= 0 && mesh.elements() > 0) ro.maxVolume = totalVolume(mesh) / mesh.elements();
    return remeshPieces(cut.mesh, ro);
}

}  // namespace cutsim
