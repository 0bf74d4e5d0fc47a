// Cutting with XFEM virtual elements (thesis sec. 2.3 and Algorithm 5; docs/method.md sec. 5).
//
// With the shifted Heaviside enrichment, each side of a cut element behaves as a copy of the
// element: same rest shape (DmInv), its own four control points (the original nodes on its side,
// duplicates for the nodes on the far side), stiffness and mass scaled by the exact volume
// fraction of its side. A copy is a "virtual element": an ordinary column of the Model, so the
// corotational force kernel runs on it unchanged (Algorithm 5 reuses the parent's data).
// Control points are shared between virtual elements on the same side of neighbouring elements
// (virtual node algorithm, Molino et al. 2004), so each piece stays one body and pieces separate
// where the cut goes through.
//
// A cut is a topology change between steps. It appends nodes and elements (existing indices keep
// their meaning), and returns what changed so the caller updates the time-step analysis locally.
#pragma once

#include "cut/polyhedron.hpp"
#include "fem/model.hpp"
#include "fem/state.hpp"
#include "mesh/embedding.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

namespace cutsim {

// How a virtual element's mass is lumped onto its four control points (thesis sec. 2.3.3).
enum class MassLumping : std::uint8_t {
    RowSum,            // m_a = rho int_side N_a: exact row sums of the side's consistent mass
    WeightedDiagonal,  // m_a = m_side int_side N_a^2 / sum_b int_side N_b^2 (Hinton-Rock-Zienkiewicz)
    Enrichment,        // m_a = m_side / 4 (Menouillard et al. 2006): mass scales with stiffness
};
MassLumping parseLumping(const std::string& name);  // row_sum | weighted_diagonal | enrichment
const char* lumpingName(MassLumping l);

struct CutOptions {
    // Enrichment keeps the step: K and M of a virtual element scale alike, so a sliver keeps its
    // parent's eigenvalues; the other lumpings give a sliver's far control point a vanishing mass.
    MassLumping lumping = MassLumping::Enrichment;
    // A side below this share of its parent's volume is merged into the other side (mass and volume
    // kept; the nodes still separate): a virtual element on a few tiny control points rings under
    // the stress it inherits. [-]
    double minFraction = 5e-2;
    // A severed piece with no prescribed node and less volume than one of its elements is fused
    // back: each of its virtual elements takes the nodes of a sibling outside the piece, so the pair
    // acts as the uncut parent. A mesh cannot resolve a piece smaller than its elements. Fused
    // elements are drawn and not cut again; pieces of an embedded object's interface elements are
    // left alone (they carry its surface).
    bool mergeDebris = true;
    // How far a debris element's sibling may have moved from it and still take it in, in element
    // sizes (cbrt of the parent's volume); 0: only a sibling at the same place. [-]
    double fuseReach = 1.0;
    // Gauss-Seidel sweeps of relaxNodes on the control points only cut elements hold, after each
    // cut: they inherit their element's stress on a few percent of the mass and would overshoot.
    // 0: off.
    int relaxIterations = 4;
    // A free control point with less than this share of its node's uncut mass is light
    // (Model::lightNodes): its motion relative to its neighbours is damped every step
    // (Stepper::dampLight). 0: off. [-]
    double lightShare = 0.05;
};

// A cutting surface in world space: the plane through `point` with unit `normal`, restricted to
// the union of convex polygons given in the plane's coordinates (origin `point`, axes u, v from
// planeAxes), or the whole plane when there are none.
struct CutSurface {
    Eigen::Vector3d point = Eigen::Vector3d::Zero();    // [m]
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit
    std::vector<std::vector<Eigen::Vector2d>> regions;  // convex polygons (u, v) [m]; empty: unbounded
};
void planeAxes(const Eigen::Vector3d& normal, Eigen::Vector3d& u, Eigen::Vector3d& v);

// The cutting edge of a blade at one pose.
struct BladeEdge {
    Eigen::Vector3d a = Eigen::Vector3d::Zero();  // one end [m]
    Eigen::Vector3d b = Eigen::Vector3d::Zero();  // the other end [m]
};

struct CutResult {
    int cut = -1;                      // id of this cut (a blade stroke keeps one id)
    int crossed = 0;                   // virtual elements the surface went through
    int split = 0;                     // of those, split into two (the rest had an empty side)
    int pending = 0;                   // elements the surface entered but did not cross yet
    int dropped = 0;                   // sides below minFraction, merged into the other side
    int merged = 0;                    // severed pieces below one element fused back (mergeDebris)
    std::vector<int> newNodes;         // appended node indices
    std::vector<int> newElements;      // appended element indices
    std::vector<int> elementSource;    // element each new element was copied from (newElements.size())
    std::vector<int> changedElements;  // elements whose nodes, fraction or mass share changed, and new ones
    std::vector<int> changedNodes;     // nodes whose mass or incident elements changed
    // Sums of V * fraction [m^3] and of the lumped masses [kg]. A cut through the whole mesh sums
    // the arrays; a blade step sums what it touched (each parent it cut against that parent's
    // material, the masses of the nodes it changed before and after) onto the sums when the engine
    // was prepared, so that it costs what it cut.
    double volumeBefore = 0, volumeAfter = 0;
    double massBefore = 0, massAfter = 0;
    double seconds = 0;  // wall time of the cut [s]
    bool changed() const { return crossed > 0; }
};

class CutEngine {
public:
    explicit CutEngine(CutOptions opts = {}) : opts_(opts) {}

    // Builds the bookkeeping of the uncut model (face adjacency, boundary). Done by the first cut
    // if not called; a scene that never cuts never pays for it.
    void prepare(const Model& m);
    bool prepared() const { return prepared_; }

    // Cuts every element the surface crosses completely, in the current (deformed) configuration.
    CutResult cut(Model& m, State& s, const CutSurface& surface);

    // Progressive cut: the blade's edge moved from `from` to `to`. The stroke cuts in the plane
    // the edge sweeps at its start (a scalpel slices in its own plane; motion out of it is
    // projected). An element is split once the swept area covers its whole cross-section, so an
    // element the blade entered stays pending until a later sweep completes it.
    // candidates: elements that may meet the swept area (e.g. from a broad phase); null: all.
    // Besides the candidates, every sweep retests the stroke's watch list (elements its plane
    // crosses, met so far and not yet split) and the face neighbours of each element it splits:
    // tissue that sags or swings out of the blade's plane while it is cut is still cut where the
    // swept area covers it, so a stroke through a moving body separates it.
    CutResult sweep(Model& m, State& s, const BladeEdge& from, const BladeEdge& to,
                    const std::vector<int>* candidates = nullptr);
    void endStroke();  // the next sweep starts a new stroke (new plane, new cut id)
    // The open stroke's plane and the area its edge has swept so far (null: no stroke open).
    const CutSurface* strokeSurface() const { return stroke_.active ? &stroke_.surface : nullptr; }

    // The surface to draw and collide with: the original boundary clipped to each virtual
    // element, plus the cut faces (EmbeddedSurface::cutFace), all riding their elements. Vertices
    // at the same place on the same nodes are one (a piece's surface is connected and shades
    // smoothly); a dropped sliver's cut and boundary faces ride an element on its side. Defined
    // in cut/cut_surface.cpp.
    EmbeddedSurface surface(const Model& m) const;

    // The same for an object given by its surface (mesh intersection, thesis ch. 6): `original` is
    // that surface as embedded in the uncut model (elements are parents). Each of its triangles is
    // split by the parents it crosses and by their cuts, each part riding the virtual element whose
    // side it is on; a triangle with a corner past the tet boundary (a visual surface) is split by
    // the cuts near it only, its cells' corners riding elements on their side. The cut faces are
    // kept only inside the original surface (winding number of the rest surface, sampled on
    // capLevels subdivision levels of each cap triangle of an element the surface crosses, each
    // sub-triangle clipped between the surface's crossings of its edges, found by bisection); at
    // the boundary they reach past it as far as the surface does. Lattice faces are never drawn:
    // the embedded surface replaces them. Defined in cut/embedded_cut.cpp.
    EmbeddedSurface surface(const Model& m, const EmbeddedSurface& original, int capLevels = 3) const;

    int cuts() const { return nextCut_; }
    int pendingElements() const { return stroke_.pending; }
    // Convex polygons of the open stroke's swept area (straight stretches are merged into one).
    int strokeRegions() const { return static_cast<int>(stroke_.surface.regions.size()); }
    int parentOf(int e) const { return prepared_ ? parent_[static_cast<size_t>(e)] : e; }
    int originalNode(int n) const { return prepared_ ? origNode_[static_cast<size_t>(n)] : n; }
    // The virtual nodes of m (nNodes, 1 = virtual; empty before any cut): copies a cut made of a node
    // for the far side of an element, on partial elements only, so they lie outside the material of
    // every element they move (ContactWorld::setSurface's `outside`).
    std::vector<std::uint8_t> virtualNodes(const Model& m) const;
    // One node's flag of virtualNodes, from its incident elements (m's incidence current): what a
    // blade step asks of a few nodes, at a cost that does not grow with the mesh.
    bool isVirtualNode(const Model& m, int n) const;
    const CutOptions& options() const { return opts_; }

private:
    struct Virtual {                // a cut virtual element
        ConvexPiece piece;          // its side of the parent, reference coordinates
        double share = 1;           // volume it stands for, as a fraction of the parent's [-]: the
                                    // piece's own plus slivers merged into it
        std::vector<Halfspace> hs;  // the sides that made it
    };
    struct Sliver {        // a side below minFraction, dropped from element `element` by cut `cut`
        int element = -1;  // the element that kept the other side
        int cut = -1;
        bool positive = false;  // the dropped side of the cut's halfspace
        ConvexPiece piece;      // the dropped side, reference coordinates of the parent
    };
    // Values of the nodes met so far (a stroke's frozen signed distances [m]): dense by node id,
    // NaN for a node not met; emplace keeps a value once set.
    class NodeValues {
    public:
        const double* find(int n) const {
            return n < static_cast<int>(v_.size()) && !std::isnan(v_[static_cast<size_t>(n)])
                       ? &v_[static_cast<size_t>(n)]
                       : nullptr;
        }
        void emplace(int n, double x) {
            if (n >= static_cast<int>(v_.size()))
                v_.resize(std::max(static_cast<size_t>(n) + 1, 2 * v_.size()),
                          std::numeric_limits<double>::quiet_NaN());
            if (std::isnan(v_[static_cast<size_t>(n)])) v_[static_cast<size_t>(n)] = x;
        }

    private:
        std::vector<double> v_;
    };
    // A watched element's two sides under the stroke's plane: fixed by the frozen distances, so
    // they are clipped once, and each sweep only retests their coverage.
    struct Section {
        std::array<double, 4> s{};  // the distances they were clipped at [m]
        ConvexPiece neg, pos;
        // The cross-section's vertices (the cut faces of the side coverage is tested on) as corner
        // weights, kept beside the sides so that each sweep's retest reads one place; points < 0:
        // more than fit, read from the side's faces.
        std::array<std::array<double, 4>, 8> w{};
        int points = -1;
    };
    struct Stroke {
        bool active = false;
        int cut = -1;
        CutSurface surface;
        std::vector<int> watch;                                // elements the plane crosses, met so far, not yet split
        int pending = 0;                                       // of those, the ones the swept area covers in part
        NodeValues nodeS;                                      // signed distance of each node met so far [m]
        std::unordered_map<int, Section> sections;             // of the watched elements
        BladeEdge last;                                        // edge at the end of the previous sweep [m]
        Eigen::Vector3d lastMotion = Eigen::Vector3d::Zero();  // midpoint motion of the previous sweep [m]
        bool lastTranslation = false;                          // the previous sweep moved the edge without turning it
    };

    CutResult apply(Model& m, State& s, const CutSurface& surface, int cutId, const std::vector<int>* candidates,
                    std::vector<int>* watchOut, NodeValues& nodeS,
                    std::unordered_map<int, Section>* sections = nullptr);
    struct Pass;
    void visitElement(Model& m, State& s, Pass& pass, int e);
    void visitFromCandidates(Model& m, State& s, Pass& pass, const std::vector<int>& candidates);
    void appendVirtuals(Model& m, State& s, Pass& pass);
    void relink(Model& m, State& s, const std::vector<int>& parents, CutResult& r, NodeValues& nodeS);
    struct NodeCopy {
        int src, orig;  // node the copy is made from, and the original node it stands for
    };
    bool gluedAcross(int e, int p, int k, int g, int q, std::vector<FaceSide>& sides) const;
    void appendNodeCopies(Model& m, State& s, const std::vector<NodeCopy>& copies);
    void finishRelink(Model& m, const std::vector<int>& parents, const std::vector<int>& repointed,
                      std::vector<int>& changedNodes, CutResult& r);
    void mergeDebris(Model& m, const Eigen::Matrix3Xd& x, CutResult& r);
    bool followFused(Model& m, CutResult& r) const;
    void relaxCutNodes(const Model& m, State& s, const CutResult& r) const;
    void markLightNodes(Model& m) const;
    void setMassShare(Model& m, int e) const;
    const std::vector<int>& virtualsOf(int parent) const;
    // Rest position of weights w in parent p's original corners [m].
    Eigen::Vector3d restOf(const Model& m, int parent, const Eigen::Vector4d& w) const {
        Eigen::Vector3d y = Eigen::Vector3d::Zero();
        for (int a = 0; a < 4; ++a) y += w[a] * m.X.col(tets0_(a, parent));
        return y;
    }
    // An element of a parent around p (sharing a corner; most shared corners, then lowest index)
    // whose piece lies on the same side of each of p's cut planes as the point at weights `at` of
    // p, or -1; its parent in carrierParent. For surface cells on a side p dropped.
    int carrierOnSide(const Model& m, int p, const std::vector<const Halfspace*>& planes, const Eigen::Vector4d& at,
                      int& carrierParent) const;
    // Triangle t of a surface with corners past the tet boundary (a visual one), split by the cuts
    // near it; each cell corner rides an element on the cell's side and in one piece (samePiece(a,
    // b): elements a and b are joined). addVertex(element, weights in its parent) gives a vertex
    // index, addTriangle(a, b, c) draws.
    struct SplitCache;
    struct PastBoundarySplit;  // the cuts near one such triangle and their sides
    struct SurfaceBuild;       // surface(m, original)'s output and phases (cut/embedded_cut.cpp)
    struct MeshSurfaceBuild;   // surface(m)'s (cut/cut_surface.cpp)
    void splitPastBoundary(const Model& m, SplitCache& cache, const EmbeddedSurface& original, int t,
                           const std::function<bool(int, int)>& samePiece,
                           const std::function<int(int, const Eigen::Vector4d&)>& addVertex,
                           const std::function<void(int, int, int)>& addTriangle) const;

    // What surface(m, original) keeps of an original surface between calls: its rest positions,
    // winding tree, triangle parts per parent and the winding numbers sampled so far. All of the
    // uncut rest configuration, so never stale; a copy of the engine starts without them. Keyed
    // by the original's address: it must stay the same object while the engine serves it.
    // A vector a copy of the engine starts without (moves keep it).
    template <class T>
    struct NotCopied {
        std::vector<T> items;
        NotCopied() = default;
        NotCopied(const NotCopied&) {}
        NotCopied& operator=(const NotCopied&) {
            items.clear();
            return *this;
        }
        NotCopied(NotCopied&&) = default;
        NotCopied& operator=(NotCopied&&) = default;
        ~NotCopied() = default;
    };
    using SplitSlot = NotCopied<std::shared_ptr<SplitCache>>;  // one cache per original surface (touched, drawn)
    SplitCache& splitCache(const Model& m, const EmbeddedSurface& original) const;

    CutOptions opts_;
    bool prepared_ = false;
    int nextCut_ = 0;
    Eigen::Matrix4Xi tets0_;                   // original elements (4 x nParents)
    std::vector<std::uint8_t> fixed0_;         // prescribed original nodes (nNodes0)
    Eigen::VectorXd mass0_;                    // each original node's mass with its elements whole (wholeMass) [kg]
    Eigen::VectorXd fraction0_;                // fraction of each parent before any cut (nParents) [-]
    double volume0_ = 0, massRef_ = 0;         // sum of V fraction, and of the node masses, when prepared
    double massChange_ = 0;                    // change of the node masses' sum in this application [kg]
    std::vector<int> visitQueue_, visitMark_;  // visitFromCandidates' queue and its marks
    int visitStamp_ = 0;
    Eigen::Matrix4Xi adj_;                    // parent across the face opposite each corner, or -1 (4 x nParents)
    std::vector<int> ringStart_, ring_;       // original node -> parents (CSR)
    std::vector<int> ringPos_;                // scratch of relink: each parent's place in a node's ring, or -1
    std::vector<int> parent_;                 // parent of each element (nElems)
    std::vector<int> origNode_;               // original node of each node (nNodes)
    std::unordered_map<int, Virtual> virt_;   // element -> its piece, for cut elements only
    std::vector<std::vector<int>> children_;  // parent -> its elements, for cut parents only (nParents)
    Stroke stroke_;
    mutable std::vector<int> single_;  // scratch for virtualsOf on an uncut parent
    struct Glued {                     // relink's answer about the element across a face, at both elements' versions
        int other = -1;
        std::uint32_t versionE = 0, versionG = 0;  // 0: never cut
        bool glued = false;
    };
    std::vector<std::vector<Glued>> gluedOf_;  // by element
    std::vector<int> pieceMark_;               // scratch of mergeDebris: exploration that reached each element
    int pieceStamp_ = 0;                       // last stamp mergeDebris put in pieceMark_
    std::unordered_map<int, int> fusedTo_;     // fused debris element -> the sibling whose nodes it uses
    // Which elements the three maps above hold, flat: most elements a blade step visits are in
    // none, and a hash lookup each (a cache miss at 100k elements) was most of the visit's time.
    enum : std::uint8_t { kVirtual = 1, kFused = 2, kChildren = 4 };
    std::vector<std::uint8_t> marks_;
    bool marked(int e, std::uint8_t bit) const {
        return static_cast<size_t>(e) < marks_.size() && (marks_[static_cast<size_t>(e)] & bit) != 0;
    }
    void setMark(int e, std::uint8_t bit) {
        if (static_cast<size_t>(e) >= marks_.size()) marks_.resize(static_cast<size_t>(e) + 1, 0);
        marks_[static_cast<size_t>(e)] |= bit;
    }
    // The cut that last split each element (its last half-space's), or -1: a stroke visits the
    // elements it already split again at each sweep.
    std::vector<int> lastCut_;
    int lastCutOf(int e) const {
        return static_cast<size_t>(e) < lastCut_.size() ? lastCut_[static_cast<size_t>(e)] : -1;
    }
    void setLastCut(int e, int cut) {
        if (static_cast<size_t>(e) >= lastCut_.size()) lastCut_.resize(static_cast<size_t>(e) + 1, -1);
        lastCut_[static_cast<size_t>(e)] = cut;
    }
    // virt_'s entries by element, flat (an unordered_map's entries keep their address). A copy
    // of the engine starts without them, its source's would point into the source: lookups of
    // the elements it has no pointer for go to virt_.
    NotCopied<Virtual*> virtOf_;
    // How often each element's sides were set (0: never cut): a kept answer about it is stale
    // once this moved on.
    std::vector<std::uint32_t> virtVersion_;
    std::uint32_t virtVersion(int e) const {
        return static_cast<size_t>(e) < virtVersion_.size() ? virtVersion_[static_cast<size_t>(e)] : 0;
    }
    Virtual& addVirtual(int e) {
        Virtual& v = virt_[e];
        const auto k = static_cast<size_t>(e);
        if (k >= virtOf_.items.size()) virtOf_.items.resize(k + 1, nullptr);
        if (k >= virtVersion_.size()) virtVersion_.resize(k + 1, 0);
        virtOf_.items[k] = &v;
        ++virtVersion_[k];
        setMark(e, kVirtual);
        return v;
    }
    const Virtual* findVirtual(int e) const {
        if (!marked(e, kVirtual)) return nullptr;
        if (static_cast<size_t>(e) < virtOf_.items.size() && virtOf_.items[static_cast<size_t>(e)])
            return virtOf_.items[static_cast<size_t>(e)];
        return &virt_.find(e)->second;
    }
    std::vector<Sliver> slivers_;  // dropped sides, drawn by surface() on their side
    mutable SplitSlot split_;
};

}  // namespace cutsim
