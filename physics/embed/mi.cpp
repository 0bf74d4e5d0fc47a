#include "embed/mi.hpp"
#include "util/memory.hpp"
#include "util/stopwatch.hpp"

#include "embed/clip.hpp"
#include "embed/winding.hpp"
#include "mesh/generate.hpp"
#include "timestep/timestep.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <string>

namespace cutsim {

namespace {

// An error of the lattice's size is the key's that set it, the surface is named beside it.
[[noreturn]] void sizeFail(const std::string& src, const MiOptions& opts, const std::string& why) {
    if (opts.sizeKey.empty()) throw InputError(src, 0, why);
    throw InputError(opts.sizeKey + ": " + why + " (surface " + src + ")");
}

// Phase 1: the lattice around the surface's box, half a cell of margin or more on every side.
// Returns the surface's extent [m].
Eigen::Vector3d layLattice(const SurfaceMesh& surfaceIn, const MiOptions& opts, const std::string& src, MiResult& r) {
    const Eigen::Vector3d lo = surfaceIn.V.rowwise().minCoeff(), hi = surfaceIn.V.rowwise().maxCoeff();
    const Eigen::Vector3d ext = hi - lo;
    if (opts.latticeCells.minCoeff() > 0) {
        r.cellSize = opts.latticeCellSize.minCoeff() > 0 ? opts.latticeCellSize : Eigen::Vector3d::Constant(opts.h);
        if (!(r.cellSize.minCoeff() > 0) || !r.cellSize.allFinite())
            throw InputError(src, 0, "a given lattice needs a cell size h > 0 (or positive cell edges)");
        r.h = r.cellSize.maxCoeff();
        r.cells = opts.latticeCells;
        r.origin = opts.latticeOrigin;
    } else {
        r.h = opts.h > 0 ? opts.h : (opts.cells > 0 ? ext.maxCoeff() / opts.cells : 0.0);
        if (!(ext.maxCoeff() > 0) || !ext.allFinite())
            throw InputError(src, 0, "the surface has no extent to lay a lattice over (all its vertices coincide)");
        if (!(ext.minCoeff() > 1e-6 * ext.maxCoeff()))
            throw InputError(src, 0,
                             "the surface is flat (extent " + std::to_string(ext.minCoeff()) + " m across, " +
                                 std::to_string(ext.maxCoeff()) + " m along): it encloses no volume");
        if (!(r.h > 0) || !std::isfinite(r.h)) sizeFail(src, opts, "cannot size the lattice: give cells >= 1 or h > 0");
        for (int k = 0; k < 3; ++k) {
            const double n = std::ceil(ext[k] / r.h) + 1;
            if (n > 1e6) sizeFail(src, opts, "lattice too fine: " + std::to_string(n) + " cells along an axis");
            r.cells[k] = static_cast<int>(n);
        }
        r.origin = 0.5 * (lo + hi) - 0.5 * r.h * r.cells.cast<double>();
        r.cellSize.setConstant(r.h);
    }
    const double nTets = 6.0 * r.cells.cast<double>().prod();
    if (nTets > static_cast<double>(opts.maxTets))
        sizeFail(src, opts,
                 "lattice of " + std::to_string(static_cast<long>(nTets)) + " tets is above the limit of " +
                     std::to_string(opts.maxTets) + "; use fewer cells or a larger h");
    // bytes per lattice tet with the lattice's own step, with margin
    checkMemory((opts.sizeKey.empty() ? src : opts.sizeKey) + ": a lattice of " +
                    std::to_string(static_cast<long>(nTets)) + " tets",
                nTets * 1000.0);
    const int nx = r.cells.x(), ny = r.cells.y(), nz = r.cells.z();
    r.lattice = boxMesh(nx * r.cellSize.x(), ny * r.cellSize.y(), nz * r.cellSize.z(), nx, ny, nz);
    r.lattice.X.colwise() += r.origin;
    r.lattice.source = src + " (lattice)";
    return ext;
}

// Phase 2a: a copy of the surface shifted by a tiny generic offset: no lattice node, edge or face
// then lies exactly on it (a surface on lattice planes is the common case), so every contact in
// clipping is transversal. The volume error is the offset times the area, ~1e-10 relative.
SurfaceMesh shiftedSurface(const SurfaceMesh& surfaceIn, const std::string& src, double hMin, MiResult& r) {
    SurfaceMesh s = surfaceIn;
    const Eigen::Vector3d shift =
        hMin * 1e-10 * Eigen::Vector3d(0.5773502691896258, 0.3141592653589793, 0.7536347069560302);
    s.V.colwise() += shift;
    // defects (welded seams, repeated or zero-area triangles) would multiply the work below
    r.cleanup = cleanSurface(s, 1e-12 * hMin * hMin);
    if (s.faces() == 0) throw InputError(src, 0, "surface has no triangle of nonzero area");
    const SurfaceCheck check = checkSurface(s);
    r.closed = check.closed();
    return s;
}

// Spatial hash (thesis Algorithm 1): cube -> triangles whose box overlaps it (CSR).
struct CubeHash {
    Eigen::Vector3d origin, cellSize;  // the lattice's lowest corner and cell edges [m]
    Eigen::Vector3i cells;             // cubes along x, y, z
    std::vector<int> start, tris;      // cube c's triangles: tris[start[c] .. start[c + 1])

    // clamped before the cast: a given lattice may not hold the surface
    int cubeOf(double x, int axis) const {
        const double c =
            std::clamp(std::floor((x - origin[axis]) / cellSize[axis]), 0.0, static_cast<double>(cells[axis] - 1));
        return static_cast<int>(c);
    }
    std::vector<int> trisOf(int c) const {
        return std::vector<int>(tris.begin() + start[c], tris.begin() + start[c + 1]);
    }
    bool touched(int c) const { return start[c + 1] > start[c]; }
};

// Phase 2b: the hash of the shifted surface over the lattice's cubes.
CubeHash hashSurface(const SurfaceMesh& s, const MiResult& r, double hMin) {
    CubeHash h{r.origin, r.cellSize, r.cells, {}, {}};
    const int nx = r.cells.x(), ny = r.cells.y(), nCubes = r.cells.prod();
    h.start.assign(static_cast<size_t>(nCubes) + 1, 0);
    std::vector<std::array<int, 6>> range(static_cast<size_t>(s.faces()));
    const double pad = 1e-9 * hMin;
    for (int f = 0; f < s.faces(); ++f) {
        const Eigen::Vector3d a = s.V.col(s.F(0, f)), b = s.V.col(s.F(1, f)), c = s.V.col(s.F(2, f));
        const Eigen::Vector3d tlo = a.cwiseMin(b).cwiseMin(c), thi = a.cwiseMax(b).cwiseMax(c);
        auto& rg = range[static_cast<size_t>(f)];
        for (int k = 0; k < 3; ++k) {
            rg[k] = h.cubeOf(tlo[k] - pad, k);
            rg[3 + k] = h.cubeOf(thi[k] + pad, k);
        }
        for (int k = rg[2]; k <= rg[5]; ++k)
            for (int j = rg[1]; j <= rg[4]; ++j)
                for (int i = rg[0]; i <= rg[3]; ++i) ++h.start[static_cast<size_t>(i + nx * (j + ny * k)) + 1];
    }
    for (int c = 0; c < nCubes; ++c) h.start[c + 1] += h.start[c];
    h.tris.resize(static_cast<size_t>(h.start[nCubes]));
    std::vector<int> fill(h.start.begin(), h.start.end() - 1);
    for (int f = 0; f < s.faces(); ++f) {
        const auto& rg = range[static_cast<size_t>(f)];
        for (int k = rg[2]; k <= rg[5]; ++k)
            for (int j = rg[1]; j <= rg[4]; ++j)
                for (int i = rg[0]; i <= rg[3]; ++i) h.tris[fill[i + nx * (j + ny * k)]++] = f;
    }
    return h;
}

// Phase 3: nodes inside by the generalized winding number (robust where ray parity is not);
// boundary when within boundaryTol * h of a triangle of a cube around the node.
void classifyNodes(const SurfaceMesh& s, const WindingTree& tree, const CubeHash& hash, const MiOptions& opts,
                   MiResult& r) {
    const int nNodes = r.lattice.nodes(), nx = r.cells.x(), ny = r.cells.y(), nz = r.cells.z();
    const int px = nx + 1, py = ny + 1;
    r.nodeInside.assign(static_cast<size_t>(nNodes), 0);
    r.nodeClass.assign(static_cast<size_t>(nNodes), NodeClass::Outside);
    const double tol = opts.boundaryTol * r.cellSize.minCoeff();
#pragma omp parallel for schedule(dynamic, 256)
    for (int n = 0; n < nNodes; ++n) {
        const Eigen::Vector3d q = r.lattice.X.col(n);
        const bool in = windingNumber(tree, q) > 0.5;
        r.nodeInside[n] = in;
        NodeClass cls = in ? NodeClass::Inside : NodeClass::Outside;
        const int i = n % px, j = (n / px) % py, k = n / (px * py);
        for (int dk = -1; dk <= 0 && cls != NodeClass::Boundary; ++dk)
            for (int dj = -1; dj <= 0 && cls != NodeClass::Boundary; ++dj)
                for (int di = -1; di <= 0 && cls != NodeClass::Boundary; ++di) {
                    const int ci = i + di, cj = j + dj, ck = k + dk;
                    if (ci < 0 || cj < 0 || ck < 0 || ci >= nx || cj >= ny || ck >= nz) continue;
                    const int c = ci + nx * (cj + ny * ck);
                    for (int t = hash.start[c]; t < hash.start[c + 1]; ++t) {
                        const int f = hash.tris[t];
                        if (pointTriangleDistance(q, s.V.col(s.F(0, f)), s.V.col(s.F(1, f)), s.V.col(s.F(2, f))) <
                            tol) {
                            cls = NodeClass::Boundary;
                            break;
                        }
                    }
                }
        r.nodeClass[n] = cls;
    }
}

// Phase 4a: a tet whose cube no triangle touches is all in or all out; returns the touched cubes,
// whose tets the next phases clip or refine.
std::vector<int> untouchedShares(const CubeHash& hash, MiResult& r) {
    std::vector<int> interfaceCubes;
    const int nCubes = r.cells.prod();
    for (int c = 0; c < nCubes; ++c) {
        const bool touched = hash.touched(c);
        for (int t = 6 * c; t < 6 * c + 6; ++t) {
            int nin = 0;
            for (int a = 0; a < 4; ++a) nin += r.nodeInside[r.lattice.tets(a, t)];
            if (!touched) {
                // closed surface: nin is 0 or 4; a broken one may disagree, then take the corner share
                r.fractionExact(t) = nin / 4.0;
                for (auto& fr : r.fractionRefined) fr(t) = nin / 4.0;
            }
        }
        if (touched) interfaceCubes.push_back(c);
    }
    return interfaceCubes;
}

// A lattice tet's corners and their inside labels.
void tetCorners(const MiResult& r, int t, Eigen::Vector3d (&p)[4], bool (&in)[4]) {
    for (int a = 0; a < 4; ++a) {
        p[a] = r.lattice.X.col(r.lattice.tets(a, t));
        in[a] = r.nodeInside[r.lattice.tets(a, t)];
    }
}

// Phase 4b: the touched tets of a closed surface, clipped exactly.
void clipInterface(const SurfaceMesh& s, const CubeHash& hash, const std::vector<int>& interfaceCubes, MiResult& r) {
    const int nic = static_cast<int>(interfaceCubes.size());
#pragma omp parallel for schedule(dynamic, 8)
    for (int ic = 0; ic < nic; ++ic) {
        const int c = interfaceCubes[ic];
        const std::vector<int> tris = hash.trisOf(c);
        for (int t = 6 * c; t < 6 * c + 6; ++t) {
            Eigen::Vector3d p[4];
            bool in[4];
            tetCorners(r, t, p, in);
            r.fractionExact(t) = tetInsideFraction(s, tris, p[0], p[1], p[2], p[3], in[3]);
        }
    }
}

// Phase 4c: the touched tets refined `levels` times; for a broken surface this is the share.
void refineInterface(const SurfaceMesh& s, const WindingTree& tree, const CubeHash& hash,
                     const std::vector<int>& interfaceCubes, int levels, MiResult& r) {
    const int nic = static_cast<int>(interfaceCubes.size());
#pragma omp parallel for schedule(dynamic, 8)
    for (int ic = 0; ic < nic; ++ic) {
        const int c = interfaceCubes[ic];
        const std::vector<int> tris = hash.trisOf(c);
        std::vector<double> perLevel;
        for (int t = 6 * c; t < 6 * c + 6; ++t) {
            Eigen::Vector3d p[4];
            bool in[4];
            tetCorners(r, t, p, in);
            if (r.closed) {
                // Local parity from corner 0, whose label the winding number gave.
                refinedInsideFraction(
                    s, tris, p, in, levels,
                    [&](const Eigen::Vector3d& x) { return insideFromAnchor(s, tris, p[0], in[0], x); }, perLevel);
            } else {
                refinedInsideFraction(
                    s, tris, p, in, levels, [&](const Eigen::Vector3d& x) { return windingNumber(tree, x) > 0.5; },
                    perLevel);
                r.fractionExact(t) = perLevel.back();
            }
            for (int l = 0; l <= levels; ++l)
                r.fractionRefined[static_cast<size_t>(l)](t) = perLevel[static_cast<size_t>(l)];
        }
    }
}

// Phase 5: element classes (thesis Algorithm 3) by inside share, so a surface poking through a tet
// between its nodes still makes it an interface element.
void classifyElements(const MiOptions& opts, MiResult& r) {
    const int ne = r.lattice.elements();
    r.elementClass.assign(static_cast<size_t>(ne), ElementClass::Outside);
    for (int t = 0; t < ne; ++t) {
        const double f = r.fractionExact(t);
        r.elementClass[t] = f >= 1 - opts.minFraction ? ElementClass::Inside
                            : f > opts.minFraction    ? ElementClass::Interface
                                                      : ElementClass::Outside;
    }
}

// Phase 6: the model of the inside and interface tets, their nodes numbered compactly. Outside
// nodes of interface tets stay as free DOFs: in XFEM they are the virtual element's control points
// (thesis 2.3, Algorithm 5); fixing them would pin the element's outside corners and stiffen the
// boundary layer, and dropping them is impossible since the element's linear field needs all four.
// Nodes of no kept tet are dropped (the thesis's "outside nodes are fixed and dropped": they carry
// no mass and no stiffness).
void buildEmbeddedModel(const Material& material, const MiOptions& opts, const std::string& src,
                        const Eigen::Vector3d& ext, MiResult& r) {
    const int ne = r.lattice.elements();
    std::vector<int> modelNode(static_cast<size_t>(r.lattice.nodes()), -1);
    for (int t = 0; t < ne; ++t) {
        if (r.elementClass[t] == ElementClass::Outside) continue;
        r.latticeElement.push_back(t);
        for (int a = 0; a < 4; ++a) {
            int& m = modelNode[r.lattice.tets(a, t)];
            if (m < 0) {
                m = static_cast<int>(r.latticeNode.size());
                r.latticeNode.push_back(r.lattice.tets(a, t));
            }
        }
    }
    if (r.latticeElement.empty()) {
        // a cell larger than the object's thinnest extent can miss it whole: the step's fault, not the surface's
        if (r.h >= ext.minCoeff() && opts.latticeCells.minCoeff() <= 0)
            sizeFail(src, opts,
                     "no lattice element lies inside the surface: the cell edge " + std::to_string(r.h) +
                         " m is not below the object's thinnest extent " + std::to_string(ext.minCoeff()) +
                         " m; use a smaller h or more cells");
        throw InputError(src, 0, "no lattice element lies inside the surface (is it inside-out or open?)");
    }
    TetMesh sub;
    sub.source = src + " (embedded)";
    sub.X.resize(3, static_cast<Eigen::Index>(r.latticeNode.size()));
    for (size_t i = 0; i < r.latticeNode.size(); ++i)
        sub.X.col(static_cast<Eigen::Index>(i)) = r.lattice.X.col(r.latticeNode[i]);
    sub.tets.resize(4, static_cast<Eigen::Index>(r.latticeElement.size()));
    for (size_t e = 0; e < r.latticeElement.size(); ++e)
        for (int a = 0; a < 4; ++a)
            sub.tets(a, static_cast<Eigen::Index>(e)) = modelNode[r.lattice.tets(a, r.latticeElement[e])];
    r.model = buildModel(sub, material);
    for (int e = 0; e < r.model.elements(); ++e) {
        const int t = r.latticeElement[static_cast<size_t>(e)];
        r.model.fraction(e) =
            r.elementClass[t] == ElementClass::Inside ? 1.0 : std::clamp(r.fractionExact(t), 0.0, 1.0);
    }
    if (opts.fixOutsideNodes)
        for (int i = 0; i < r.model.nodes(); ++i) {
            const int n = r.latticeNode[static_cast<size_t>(i)];
            if (r.nodeClass[n] == NodeClass::Outside) r.model.fixed[i] = 1;
        }
    updateMasses(r.model);
}

// Phase 7: the render surface: each input vertex rides the kept element holding it (barycentric
// weights).
void embedSurface(const SurfaceMesh& surfaceIn, const CubeHash& hash, MiResult& r) {
    const int ne = r.lattice.elements(), nx = r.cells.x(), ny = r.cells.y(), nz = r.cells.z();
    std::vector<int> modelElem(static_cast<size_t>(ne), -1);
    for (size_t e = 0; e < r.latticeElement.size(); ++e) modelElem[r.latticeElement[e]] = static_cast<int>(e);
    const int nv = surfaceIn.vertices();
    r.surface.triangles = surfaceIn.F;
    r.surface.cutId.assign(static_cast<size_t>(surfaceIn.faces()), -1);
    r.surface.element.assign(static_cast<size_t>(nv), -1);
    r.surface.weights = Eigen::Matrix4Xd::Zero(4, nv);
    auto weightsIn = [&](int t, const Eigen::Vector3d& v) {
        const auto& T = r.lattice.tets;
        return barycentric(v, r.lattice.X.col(T(0, t)), r.lattice.X.col(T(1, t)), r.lattice.X.col(T(2, t)),
                           r.lattice.X.col(T(3, t)));
    };
#pragma omp parallel for schedule(static)
    for (int v = 0; v < nv; ++v) {
        const Eigen::Vector3d x = surfaceIn.V.col(v);
        const int ci = hash.cubeOf(x.x(), 0), cj = hash.cubeOf(x.y(), 1), ck = hash.cubeOf(x.z(), 2);
        int best = -1;
        double bestScore = -1e300;
        Eigen::Vector4d bestW = Eigen::Vector4d::Zero();
        // own cube first, then its neighbours when no kept tet of it holds the vertex
        for (int ring = 0; ring <= 1 && bestScore < -1e-9; ++ring)
            for (int dk = -ring; dk <= ring; ++dk)
                for (int dj = -ring; dj <= ring; ++dj)
                    for (int di = -ring; di <= ring; ++di) {
                        const int i = ci + di, j = cj + dj, k = ck + dk;
                        if (i < 0 || j < 0 || k < 0 || i >= nx || j >= ny || k >= nz) continue;
                        const int c = i + nx * (j + ny * k);
                        for (int t = 6 * c; t < 6 * c + 6; ++t) {
                            if (modelElem[t] < 0) continue;
                            const Eigen::Vector4d w = weightsIn(t, x);
                            if (w.minCoeff() > bestScore) {
                                bestScore = w.minCoeff();
                                best = t;
                                bestW = w;
                            }
                        }
                    }
        if (best < 0) {
            // A broken surface can leave a vertex far from every kept tet: follow the nearest one.
            double d2 = 1e300;
            for (size_t e = 0; e < r.latticeElement.size(); ++e) {
                const int t = r.latticeElement[e];
                Eigen::Vector3d c = Eigen::Vector3d::Zero();
                for (int a = 0; a < 4; ++a) c += 0.25 * r.lattice.X.col(r.lattice.tets(a, t));
                if ((c - x).squaredNorm() < d2) {
                    d2 = (c - x).squaredNorm();
                    best = t;
                }
            }
            bestW = weightsIn(best, x);
        }
        r.surface.element[static_cast<size_t>(v)] = modelElem[best];
        r.surface.weights.col(v) = bestW;
    }
}

}  // namespace

int MiResult::count(ElementClass c) const {
    return static_cast<int>(std::count(elementClass.begin(), elementClass.end(), c));
}
int MiResult::count(NodeClass c) const { return static_cast<int>(std::count(nodeClass.begin(), nodeClass.end(), c)); }

double MiResult::embeddedVolume() const {
    double v = 0;
    for (int e = 0; e < model.elements(); ++e) v += model.volume(e) * model.fraction(e);
    return v;
}

SurfaceMesh boxSurface(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
    SurfaceMesh s;
    s.V.resize(3, 8);
    for (int c = 0; c < 8; ++c)
        s.V.col(c) << (c & 1 ? hi.x() : lo.x()), (c & 2 ? hi.y() : lo.y()), (c & 4 ? hi.z() : lo.z());
    // two triangles per face, counter-clockwise seen from outside
    s.F.resize(3, 12);
    s.F << 0, 0, 4, 4, 0, 0, 2, 2, 0, 0, 1, 1, 2, 3, 5, 7, 1, 5, 7, 6, 4, 6, 3, 7, 3, 1, 7, 6, 5, 4, 3, 7, 6, 2, 7, 5;
    s.source = "box";
    return s;
}

MiResult buildMi(const SurfaceMesh& surfaceIn, const Material& material, const MiOptions& opts) {
    const std::string& src = surfaceIn.source.empty() ? std::string("surface") : surfaceIn.source;
    if (surfaceIn.faces() == 0) throw InputError(src, 0, "surface has no triangles");
    if (!surfaceIn.V.allFinite()) throw InputError(src, 0, "surface has a non-finite coordinate");
    MiResult r;

    // 1. Lattice around the surface's box.
    auto t0 = WallClock::now();
    const Eigen::Vector3d ext = layLattice(surfaceIn, opts, src, r);
    const double hMin = r.cellSize.minCoeff();  // scale of the tolerances below
    r.seconds.lattice = secondsSince(t0);

    // 2. The surface shifted off the lattice's planes, and its spatial hash.
    t0 = WallClock::now();
    const SurfaceMesh s = shiftedSurface(surfaceIn, src, hMin, r);
    const CubeHash hash = hashSurface(s, r, hMin);
    r.seconds.hash = secondsSince(t0);

    // 3. Nodes: inside, outside or on the boundary.
    t0 = WallClock::now();
    const WindingTree tree = buildWindingTree(s);
    classifyNodes(s, tree, hash, opts, r);
    r.seconds.nodes = secondsSince(t0);

    // 4. Inside share of every lattice tet. A tet whose cube no triangle touches is all in or all
    // out; the others are clipped exactly (closed surface) or refined with winding numbers (broken).
    t0 = WallClock::now();
    const int ne = r.lattice.elements();
    r.fractionExact = Eigen::VectorXd::Zero(ne);
    const int levels = r.closed ? opts.refineLevels : std::max(opts.refineLevels, 2);
    if (levels > 0) r.fractionRefined.assign(static_cast<size_t>(levels) + 1, Eigen::VectorXd::Zero(ne));
    const std::vector<int> interfaceCubes = untouchedShares(hash, r);
    if (r.closed) clipInterface(s, hash, interfaceCubes, r);
    r.seconds.volumes = secondsSince(t0);
    t0 = WallClock::now();
    if (levels > 0) refineInterface(s, tree, hash, interfaceCubes, levels, r);
    r.seconds.refine = secondsSince(t0);

    // 5. Element classes by inside share.
    classifyElements(opts, r);

    // 6. The model: inside and interface tets.
    t0 = WallClock::now();
    buildEmbeddedModel(material, opts, src, ext, r);
    r.seconds.model = secondsSince(t0);

    // 7. The render surface on the kept elements.
    t0 = WallClock::now();
    embedSurface(surfaceIn, hash, r);
    r.seconds.embed = secondsSince(t0);

    // 8. Keep the lattice's step (thesis sec. 6.3 expects it; not every cut gives it exactly).
    if (opts.keepLatticeStep) {
        t0 = WallClock::now();
        r.dtLattice = exactCriticalDt(buildModel(r.lattice, material)).dt;
        if (!(r.dtLattice > 0) || !std::isfinite(r.dtLattice))
            throw InputError(src, 0,
                             "the lattice's stable step is " + std::to_string(r.dtLattice) +
                                 " s: check the material and the scale");
        r.massScaling = keepStep(r.model, r.dtLattice);
        r.seconds.keepStep = secondsSince(t0);
    }
    return r;
}

int miBarCellsAlong(int cellsAcross) { return 10 * cellsAcross + 1; }

std::vector<MiBarRow> miBarRows(const MiBarOptions& o, const std::vector<double>& kept) {
    if (o.cellsAcross < 1 || o.cellsAlong < 0 || !(o.scale > 0))
        throw InputError("mi-bar: need cellsAcross >= 1, cellsAlong >= 0 and scale > 0");
    const int along = o.cellsAlong > 0 ? o.cellsAlong : miBarCellsAlong(o.cellsAcross);
    MiOptions mo;
    mo.latticeCells = Eigen::Vector3i(o.cellsAcross, o.cellsAcross, along);
    mo.latticeCellSize = Eigen::Vector3d(o.scale / o.cellsAcross, o.scale / o.cellsAcross, 10 * o.scale / along);
    mo.latticeOrigin.setZero();
    const Model lattice =
        buildModel(boxMesh(o.scale, o.scale, 10 * o.scale, o.cellsAcross, o.cellsAcross, along), o.material);
    const double dtLattice = exactCriticalDt(lattice).dt;
    std::vector<MiBarRow> rows;
    for (double k : kept) {
        if (!(k > 0 && k <= 1)) throw InputError("mi-bar: kept share must be in (0, 1], got " + std::to_string(k));
        const SurfaceMesh bar =
            boxSurface(Eigen::Vector3d(0, 0, 10 * o.scale * (1 - k)), Eigen::Vector3d(o.scale, o.scale, 10 * o.scale));
        const MiResult r = buildMi(bar, o.material, mo);
        MiBarRow row;
        row.kept = k;
        row.nodes = r.model.nodes();
        row.elements = r.model.elements();
        row.interfaceElements = r.count(ElementClass::Interface);
        row.volume = r.embeddedVolume();
        const StiffnessRows sr = assembleStiffnessRows(r.model);
        row.dtExact = exactCriticalDt(r.model, sr).dt;
        row.dtCertified = certifiedDt(r.model, sr);
        row.dtLattice = dtLattice;
        MiOptions fixedOpts = mo;
        fixedOpts.fixOutsideNodes = true;
        const Model fixedModel = buildMi(bar, o.material, fixedOpts).model;
        row.dtOutsideFixed = exactCriticalDt(fixedModel).dt;
        row.freeNodesOutsideFixed = fixedModel.freeDofs() / 3;
        Model keptModel = r.model;  // as MiOptions::keepLatticeStep, with the lattice's step known
        row.addedMassFraction = keepStep(keptModel, dtLattice).massFraction;
        row.dtKept = exactCriticalDt(keptModel).dt;
        rows.push_back(row);
    }
    return rows;
}

}  // namespace cutsim
