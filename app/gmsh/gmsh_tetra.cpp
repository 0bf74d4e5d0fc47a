// cutsim-gmsh-tetra SURFACE OUT SIZE [BOUND]: the tet mesh of a closed surface by Gmsh (Geuzaine
// and Remacle 2009), for `cutsim tetra --mesher gmsh`. The surface's patches between creases are
// reparametrized and remeshed at the target edge (new points lie on the input triangles, creases
// kept as curves), then filled by HXT (Marot et al. 2019) and Gmsh's optimiser. Where the input
// surface lies farther than BOUND [m] from the mesh's boundary (a thin tip the target edge cannot
// follow), the mesh is made again with smaller elements there. A program of its own: Gmsh 4.8
// bundles TetGen's symbols, which clash with the TetGen cutsim links.
// Prints one JSON line (the crease angle used, the refinements, the seconds of each phase); exit 1
// when no crease angle gives a mesh.
#include "embed/surface_distance.hpp"
#include "mesh/io.hpp"

#include <gmsh.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <unordered_map>
#include <string>
#include <vector>

namespace cutsim {
namespace {

// Gmsh 4.8's split of a surface into patches it can parametrize fails on some surfaces at some
// crease angles ("wrong topology of boundary mesh"); the angles are tried in this order, the
// first whose surface mesh passes kSmallestEdge is kept. Smaller angles keep more creases.
constexpr double kCreaseAngles[] = {40, 20, 10, 60, 70, 80, 90};
// A split that leaves a surface triangle whose longest edge is under this share of the target edge
// (a sliver patch at a tip, its curves meshed finely) makes the step small; the next angle is
// tried, and the split whose smallest triangle is largest kept when none passes.
constexpr double kSmallestEdge = 0.3;
// Splits that give a surface mesh tried at most (their meshing is the costly part of a failed try).
constexpr int kMaxSplits = 2;
// Refinement where the surface lies past the bound: the local edge there shrinks by this factor
// per pass, down to this share of the target edge, and grows away from it by this slope.
constexpr double kShrink = 0.6, kMinShare = 0.35, kGrading = 0.5;
constexpr int kRefinements = 3;
// At most this share of the samples is refined in a pass (else the mesh is kept as it is).
constexpr double kMaxRefinedShare = 0.05;
// Points farther apart than this share of the bound are refined: Gmsh places its points anew in
// each pass, so a place just inside the bound in one pass may lie past it in the next.
constexpr double kRefineAt = 0.6;
// The surfaces are compared at points this share of the target edge apart.
constexpr double kSampling = 0.5;
// The refinement's edges are sampled for Gmsh at nodes this share of the target edge apart.
constexpr double kGridStep = 0.125;

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

struct GmshRun {
    SurfaceMesh surface;  // the surface mesh Gmsh made (the tets' boundary)
    TetMesh mesh;
    double angle = 0, surfaceSeconds = 0, volumeSeconds = 0;
    double smallestEdge = 0;  // the smallest longest edge of a surface triangle, over the target edge
    int refinements = 0, refinedPoints = 0;
};

// Local target edges: from points p_a with edge h_a, the edge at x is min(size, h_a + kGrading |x - p_a|).
class SizeField {
public:
    explicit SizeField(double size) : size_(size), cell_(size / kGrading) {}
    bool empty() const { return points_.empty(); }
    double at(const Eigen::Vector3d& x) const {
        double h = size_;
        const std::array<long, 3> c = cellOf(x);
        for (long dz = -1; dz <= 1; ++dz)
            for (long dy = -1; dy <= 1; ++dy)
                for (long dx = -1; dx <= 1; ++dx) {
                    const auto it = cells_.find(key({c[0] + dx, c[1] + dy, c[2] + dz}));
                    if (it == cells_.end()) continue;
                    for (int a : it->second) h = std::min(h, edges_[a] + kGrading * (x - points_[a]).norm());
                }
        return h;
    }
    void add(const Eigen::Vector3d& p, double h) {
        cells_[key(cellOf(p))].push_back(static_cast<int>(points_.size()));
        points_.push_back(p);
        edges_.push_back(h);
    }

private:
    // a cell as wide as the reach of a point (h_a >= 0), so the 27 around x hold every point that
    // lowers the edge at x
    std::array<long, 3> cellOf(const Eigen::Vector3d& x) const {
        return {std::lround(std::floor(x[0] / cell_)), std::lround(std::floor(x[1] / cell_)),
                std::lround(std::floor(x[2] / cell_))};
    }
    static std::uint64_t key(const std::array<long, 3>& c) {
        return (static_cast<std::uint64_t>(c[0] & 0x1fffff) << 42) |
               (static_cast<std::uint64_t>(c[1] & 0x1fffff) << 21) | static_cast<std::uint64_t>(c[2] & 0x1fffff);
    }
    double size_, cell_;
    std::vector<Eigen::Vector3d> points_;
    std::vector<double> edges_;
    std::unordered_map<std::uint64_t, std::vector<int>> cells_;
    friend class SizeGrid;
};

// A SizeField sampled on a grid and interpolated (trilinear): Gmsh asks for the edge many times
// per point it places, and a grid answers in constant time. Its nodes are kGridStep x size apart
// (at most 160 along the longest side of the field's box), which blurs a point's cone by under a
// tenth of the target edge.
class SizeGrid {
public:
    explicit SizeGrid(const SizeField& f) : size_(f.size_) {
        if (f.points_.empty()) return;
        const double reach = f.size_ / kGrading;
        lo_ = hi_ = f.points_[0];
        for (const Eigen::Vector3d& p : f.points_) lo_ = lo_.cwiseMin(p), hi_ = hi_.cwiseMax(p);
        lo_.array() -= reach;
        hi_.array() += reach;
        step_ = std::max(kGridStep * f.size_, (hi_ - lo_).maxCoeff() / 160);
        for (int k = 0; k < 3; ++k) n_[k] = static_cast<int>(std::ceil((hi_[k] - lo_[k]) / step_)) + 1;
        h_.assign(static_cast<size_t>(n_[0]) * n_[1] * n_[2], f.size_);
        const int r = static_cast<int>(std::ceil(reach / step_));
        for (size_t a = 0; a < f.points_.size(); ++a) {
            const Eigen::Vector3d& p = f.points_[a];
            int c[3];
            for (int k = 0; k < 3; ++k) c[k] = static_cast<int>(std::lround((p[k] - lo_[k]) / step_));
            for (int z = std::max(0, c[2] - r); z <= std::min(n_[2] - 1, c[2] + r); ++z)
                for (int y = std::max(0, c[1] - r); y <= std::min(n_[1] - 1, c[1] + r); ++y)
                    for (int x = std::max(0, c[0] - r); x <= std::min(n_[0] - 1, c[0] + r); ++x) {
                        const Eigen::Vector3d q = lo_ + step_ * Eigen::Vector3d(x, y, z);
                        double& h = h_[index(x, y, z)];
                        h = std::min(h, f.edges_[a] + kGrading * (q - p).norm());
                    }
        }
    }
    double at(const Eigen::Vector3d& x) const {
        if (h_.empty() || (x.array() < lo_.array()).any() || (x.array() >= hi_.array()).any()) return size_;
        const Eigen::Vector3d u = (x - lo_) / step_;
        int i[3];
        double t[3];
        for (int k = 0; k < 3; ++k) {
            i[k] = std::min(n_[k] - 2, static_cast<int>(u[k]));
            t[k] = u[k] - i[k];
        }
        double h = 0;
        for (int c = 0; c < 8; ++c) {
            const int dx = c & 1, dy = (c >> 1) & 1, dz = c >> 2;
            h += (dx ? t[0] : 1 - t[0]) * (dy ? t[1] : 1 - t[1]) * (dz ? t[2] : 1 - t[2]) *
                 h_[index(i[0] + dx, i[1] + dy, i[2] + dz)];
        }
        return h;
    }

private:
    size_t index(int x, int y, int z) const {
        return (static_cast<size_t>(z) * static_cast<size_t>(n_[1]) + static_cast<size_t>(y)) *
                   static_cast<size_t>(n_[0]) +
               static_cast<size_t>(x);
    }
    double size_, step_ = 1;
    Eigen::Vector3d lo_ = Eigen::Vector3d::Zero(), hi_ = Eigen::Vector3d::Zero();
    int n_[3] = {0, 0, 0};
    std::vector<double> h_;
};

// The surface mesh Gmsh made.
SurfaceMesh madeSurface() {
    std::vector<std::size_t> nodeTags, elemTags, elemNodes;
    std::vector<double> coord, param;
    gmsh::model::mesh::getNodes(nodeTags, coord, param, 2, -1, true, false);
    std::unordered_map<std::size_t, int> index;
    SurfaceMesh m;
    m.V.resize(3, static_cast<Eigen::Index>(nodeTags.size()));
    for (size_t i = 0; i < nodeTags.size(); ++i) {
        index[nodeTags[i]] = static_cast<int>(i);
        m.V.col(static_cast<Eigen::Index>(i)) = Eigen::Vector3d(coord[3 * i], coord[3 * i + 1], coord[3 * i + 2]);
    }
    gmsh::model::mesh::getElementsByType(2, elemTags, elemNodes);
    m.F.resize(3, static_cast<Eigen::Index>(elemNodes.size() / 3));
    for (size_t e = 0; e < elemNodes.size(); ++e)
        m.F(static_cast<Eigen::Index>(e % 3), static_cast<Eigen::Index>(e / 3)) = index.at(elemNodes[e]);
    return m;
}

// The smallest longest edge of a triangle of s.
double smallestLongestEdge(const SurfaceMesh& s) {
    double smallest = std::numeric_limits<double>::infinity();
    for (int f = 0; f < s.faces(); ++f) {
        const Eigen::Vector3d a = s.V.col(s.F(0, f)), b = s.V.col(s.F(1, f)), c = s.V.col(s.F(2, f));
        smallest = std::min(smallest, std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()}));
    }
    return smallest;
}

// The surface remeshed at crease angle `angle` [deg] with the local edges of `field` (the tets
// are fillVolume's); throws (Gmsh's message) when Gmsh fails.
GmshRun surfaceAt(const SurfaceMesh& s, double size, double angle, const SizeField& field) {
    gmsh::clear();
    gmsh::model::add("tetra");
    const int surf = gmsh::model::addDiscreteEntity(2);
    std::vector<std::size_t> tags(static_cast<size_t>(s.vertices()));
    std::vector<double> xyz;
    for (int i = 0; i < s.vertices(); ++i) {
        tags[static_cast<size_t>(i)] = static_cast<std::size_t>(i) + 1;
        for (int k = 0; k < 3; ++k) xyz.push_back(s.V(k, i));
    }
    gmsh::model::mesh::addNodes(2, surf, tags, xyz);
    std::vector<std::size_t> tri;
    for (int f = 0; f < s.faces(); ++f)
        for (int k = 0; k < 3; ++k) tri.push_back(static_cast<std::size_t>(s.F(k, f)) + 1);
    gmsh::model::mesh::addElementsByType(surf, 2, {}, tri);
    GmshRun run;
    run.angle = angle;
    double t = now();
    // patches between edges turning by more than `angle`, split further until each can be mapped
    // to the plane (forReparametrization); curves not split at corners (curveAngle 180)
    gmsh::model::mesh::classifySurfaces(angle * M_PI / 180, true, true, M_PI);
    gmsh::model::mesh::createGeometry();
    std::vector<std::pair<int, int>> patches;
    gmsh::model::getEntities(patches, 2);
    std::vector<int> loop;
    for (const auto& p : patches) loop.push_back(p.second);
    gmsh::model::geo::addVolume({gmsh::model::geo::addSurfaceLoop(loop)});
    gmsh::model::geo::synchronize();
    gmsh::option::setNumber("Mesh.MeshSizeMin", 0);
    gmsh::option::setNumber("Mesh.MeshSizeMax", size);
    gmsh::option::setNumber("Mesh.MeshSizeFromPoints", 0);
    gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
    gmsh::option::setNumber("Mesh.MeshSizeExtendFromBoundary", 1);
    gmsh::option::setNumber("Mesh.Algorithm", 6);     // Frontal-Delaunay on the patches
    gmsh::option::setNumber("Mesh.Algorithm3D", 10);  // HXT
    gmsh::option::setNumber("Mesh.Optimize", 1);
    if (field.empty())
        gmsh::model::mesh::removeSizeCallback();
    else
        gmsh::model::mesh::setSizeCallback(
            [g = std::make_shared<const SizeGrid>(field)](int, int, double x, double y, double z) {
                return g->at(Eigen::Vector3d(x, y, z));
            });
    gmsh::model::mesh::generate(2);
    run.surface = madeSurface();
    run.surfaceSeconds = now() - t;
    run.smallestEdge = smallestLongestEdge(run.surface) / size;
    return run;
}

// The volume inside the surface surfaceAt made last, filled.
void fillVolume(GmshRun& run) {
    const double t = now();
    gmsh::model::mesh::generate(3);
    run.volumeSeconds = now() - t;
    std::vector<std::size_t> nodeTags, elemTags, elemNodes;
    std::vector<double> coord, param;
    gmsh::model::mesh::getNodes(nodeTags, coord, param, -1, -1, true, false);
    gmsh::model::mesh::getElementsByType(4, elemTags, elemNodes);
    if (elemTags.empty()) throw std::runtime_error("Gmsh made no tetrahedron");
    // the nodes the tets use, numbered in order of first use
    std::map<std::size_t, Eigen::Index> at;
    for (size_t i = 0; i < nodeTags.size(); ++i) at[nodeTags[i]] = static_cast<Eigen::Index>(i);
    std::map<std::size_t, int> index;
    TetMesh& m = run.mesh;
    m.tets.resize(4, static_cast<Eigen::Index>(elemTags.size()));
    std::vector<Eigen::Index> from;
    for (size_t e = 0; e < elemTags.size(); ++e)
        for (int k = 0; k < 4; ++k) {
            const auto [it, fresh] = index.try_emplace(elemNodes[4 * e + k], static_cast<int>(from.size()));
            if (fresh) from.push_back(at.at(elemNodes[4 * e + k]));
            m.tets(k, static_cast<Eigen::Index>(e)) = it->second;
        }
    m.X.resize(3, static_cast<Eigen::Index>(from.size()));
    for (size_t i = 0; i < from.size(); ++i)
        for (int k = 0; k < 3; ++k) m.X(k, static_cast<Eigen::Index>(i)) = coord[3 * static_cast<size_t>(from[i]) + k];
    for (int e = 0; e < m.elements(); ++e)
        if (tetSignedVolume(m, e) < 0) std::swap(m.tets(2, e), m.tets(3, e));
}

// Points of a surface no farther apart than `spacing`: each triangle's corners and a grid of
// barycentric points.
Eigen::Matrix3Xd samplesOf(const SurfaceMesh& s, double spacing) {
    std::vector<Eigen::Vector3d> p;
    for (int f = 0; f < s.faces(); ++f) {
        const Eigen::Vector3d a = s.V.col(s.F(0, f)), b = s.V.col(s.F(1, f)), c = s.V.col(s.F(2, f));
        const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
        const int n = std::max(1, static_cast<int>(std::ceil(longest / spacing)));
        for (int i = 0; i <= n; ++i)
            for (int j = 0; i + j <= n; ++j) p.push_back(a + (b - a) * i / n + (c - a) * j / n);
    }
    Eigen::Matrix3Xd out(3, static_cast<Eigen::Index>(p.size()));
    for (size_t i = 0; i < p.size(); ++i) out.col(static_cast<Eigen::Index>(i)) = p[i];
    return out;
}

// The surface at `angle`, made again (at most kRefinements times) with smaller elements around
// the points where it and the input lie farther than `bound` apart (both ways); the pass that lies
// nearest is kept, and is what Gmsh holds on return.
GmshRun refinedAt(const SurfaceMesh& s, double size, double angle, double bound, GmshRun run) {
    if (!(bound > 0)) return run;
    const double spacing = kSampling * size;
    const Eigen::Matrix3Xd samples = samplesOf(s, spacing);
    SizeField field(size), bestField(size);
    GmshRun best;
    double bestDistance = std::numeric_limits<double>::infinity();
    bool bestIsLast = true;
    for (int pass = 0;; ++pass) {
        // both ways: the input's points far from the new surface (a tip cut off), the new
        // surface's far from the input (a chord across a thin rim)
        const Eigen::Matrix3Xd back = samplesOf(run.surface, spacing);
        const std::vector<double> d = pointDistances(samples, run.surface), e = pointDistances(back, s);
        const double distance = std::max(*std::max_element(d.begin(), d.end()), *std::max_element(e.begin(), e.end()));
        const int refinements = run.refinements, refined = run.refinedPoints;
        const double seconds = run.surfaceSeconds;
        bestIsLast = distance < bestDistance;
        if (bestIsLast) {
            bestDistance = distance;
            best = run;
            bestField = field;
        }
        if (distance <= bound || pass == kRefinements) break;
        int far = 0;
        auto refine = [&](const Eigen::Vector3d& p, double dist) {
            if (!(dist > kRefineAt * bound)) return;
            const double h = field.at(p);
            if (h <= kMinShare * size * (1 + 1e-9)) return;  // as fine as it gets
            field.add(p, std::max(kMinShare * size, kShrink * h));
            ++far;
        };
        for (Eigen::Index i = 0; i < samples.cols(); ++i) refine(samples.col(i), d[static_cast<size_t>(i)]);
        for (Eigen::Index i = 0; i < back.cols(); ++i) refine(back.col(i), e[static_cast<size_t>(i)]);
        // refinement is for a few thin places: past this share, the target edge is too coarse
        // for the surface, and Gmsh's remeshing of that much would cost more than the fill
        if (far == 0 || far > kMaxRefinedShare * static_cast<double>(samples.cols() + back.cols())) break;
        run = surfaceAt(s, size, angle, field);
        run.refinements = refinements + 1;
        run.refinedPoints = refined + far;
        run.surfaceSeconds += seconds;
    }
    if (!bestIsLast) {  // Gmsh holds a later pass: the kept one made again
        const GmshRun again = surfaceAt(s, size, angle, bestField);
        best.surface = again.surface;
        best.surfaceSeconds += again.surfaceSeconds;
    }
    return best;
}

}  // namespace
}  // namespace cutsim

int main(int argc, char** argv) {
    if (argc != 4 && argc != 5) {
        std::fprintf(stderr, "usage: cutsim-gmsh-tetra SURFACE OUT SIZE [BOUND]\n");
        return 2;
    }
    try {
        using namespace cutsim;
        const SurfaceMesh s = readSurfaceMesh(argv[1]);
        const double size = std::atof(argv[3]), bound = argc == 5 ? std::atof(argv[4]) : 0;
        gmsh::initialize();
        gmsh::option::setNumber("General.Terminal", 0);
        // one thread everywhere: HXT's result depends on the thread count, and the mesh must not
        // depend on the machine
        for (const char* o :
             {"General.NumThreads", "Mesh.MaxNumThreads1D", "Mesh.MaxNumThreads2D", "Mesh.MaxNumThreads3D"})
            gmsh::option::setNumber(o, 1);
        std::string errors;
        std::optional<GmshRun> run;
        double fallback = 0, fallbackEdge = -1, last = 0;  // the angle whose smallest edge is largest
        int made = 0;
        GmshRun kept;  // the fallback's surface
        const SizeField uniform(size);
        for (const double angle : kCreaseAngles) {
            try {
                GmshRun r = surfaceAt(s, size, angle, uniform);
                last = angle;
                if (r.smallestEdge >= kSmallestEdge) {
                    run = std::move(r);
                    break;
                }
                if (r.smallestEdge > fallbackEdge) {
                    fallback = angle, fallbackEdge = r.smallestEdge;
                    kept = std::move(r);
                }
                if (++made == kMaxSplits) break;
            } catch (const std::string& e) {  // Gmsh 4.8 throws its last error message
                errors += (errors.empty() ? "" : "; ") + std::to_string(int(angle)) + " deg: " + e;
            } catch (const std::runtime_error& e) {
                errors += (errors.empty() ? "" : "; ") + std::to_string(int(angle)) + " deg: " + e.what();
            }
        }
        // Gmsh holds the last split made: the fallback is made again unless it is that one
        if (!run && fallbackEdge >= 0) run = fallback == last ? std::move(kept) : surfaceAt(s, size, fallback, uniform);
        if (run) {
            const double angle = run->angle;
            run = refinedAt(s, size, angle, bound, std::move(*run));
            fillVolume(*run);
            writeMsh22(argv[2], run->mesh);
            std::printf("{\"angle\": %g, \"refinements\": %d, \"refined_points\": %d, \"smallest_edge\": %.6f, "
                        "\"surface_seconds\": %.6f, \"volume_seconds\": %.6f}\n",
                        run->angle, run->refinements, run->refinedPoints, run->smallestEdge, run->surfaceSeconds,
                        run->volumeSeconds);
            gmsh::finalize();
            return 0;
        }
        gmsh::finalize();
        std::fprintf(stderr, "error: Gmsh could not mesh the surface at any crease angle (%s)\n", errors.c_str());
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
    } catch (const std::string& e) {
        std::fprintf(stderr, "error: Gmsh: %s\n", e.c_str());
    }
    return 1;
}
