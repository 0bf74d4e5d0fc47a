// Tool-tissue contact through Bullet. Created only when a scene has tools: no Bullet world
// without a tool.
//
// Representation: the surface is a cloud of contact points (its vertices plus points on its edges
// and faces, at most `spacing` apart). A btDbvt over triangle boxes is queried with each tool
// part's box (Bullet's box of its shape at its pose, without the 2 cm contact breaking threshold
// the btCollisionWorld's broad phase adds for metre-sized bodies); the candidate triangles' points get their
// signed distance to the tool, in closed form for spheres, capsules and boxes and from Bullet's
// GJK/EPA for hulls (btGjkEpaSolver2::SignedDistance, as Bullet's soft-body nodes do).
// The cost follows what touches: each step bounds how far any point drifted from where the tree
// holds it (the farthest surface node from its reference times the largest weight sum, one pass
// over the surface's nodes, not its points); a tool whose box misses the tree's root grown by that
// bound costs nothing more; with a tool near, only the leaves within that bound of its box are
// visited and their moved nodes' triangles refitted, in place (contact/surface_tree.cpp), and a
// candidate triangle whose own box misses the tool's leaves its points untested. The trees are
// made only when a shape first comes near after the surface changed, and the faces of a blade's
// own cut sit in a tree of their own that the blade skips. A static collider is queried through the
// trees only when a piece moved enough since the last query for a new point to reach it: in between
// the piece tests the points it kept within a band of the collider (resting contact costs its points).
// Points are interpolated only when their triangle is a candidate.
// This was the cheapest of the representations measured (bench/micro/contact_bench.cpp): a
// collision object per point or a refitted btBvhTriangleMeshShape cost far more per step.
//
// Two contact models act through the same points (contact.model in a scene):
// - projection (project, after the step's integration): kinematic contact as explicit codes use it
//   for rigid walls; each point inside a tool or collider gets the impulse that stops its approach,
//   with Coulomb friction, and is moved back onto the surface. No stiffness, so nothing to keep
//   below a stable limit, and no penetration beyond one step's motion.
// - penalty (addForces, before the forces): f = s_p max(0, k d - c v_n) n per point inside a tool
//   (s_p its mass scale, scaleByMass; d depth, n the way out, v_n the separating speed relative to
//   the tool).
// Both act on the mesh nodes through the transpose of the interpolation x_p = sum_i w_i x_i, so they
// work the same for cut faces and embedded (MI) surfaces. The reaction on each tool is minus what
// its points received (force, or momentum over the step).
// Static colliders (contact/collider.hpp) are shapes that do not move: a plane is a half-space
// tested against the triangle tree directly; boxes, spheres and convex meshes are Bullet objects.
#pragma once

#include "contact/collider.hpp"
#include "contact/tool.hpp"
#include "fem/model.hpp"
#include "mesh/embedding.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <memory>
#include <vector>

namespace cutsim {

// Contact points of an embedded surface; each point follows up to 12 nodes. Points 0..nVerts-1
// are the surface vertices; every other point lies on one triangle (edge or face), inside the
// triangle's box, so a tree over triangle boxes finds them.
struct ContactPoints {
    static constexpr int kMaxNodes = 12;
    Eigen::Matrix<int, kMaxNodes, Eigen::Dynamic> nodes;       // node indices (12 x nPoints); unused slots: node 0
    Eigen::Matrix<double, kMaxNodes, Eigen::Dynamic> weights;  // interpolation weights (12 x nPoints) [-]; unused: 0
    std::vector<std::uint8_t> count;                           // used slots of each point, packed first (nPoints)
    Eigen::Matrix3Xi triangles;                                // surface triangles as vertex point indices (3 x nTris)
    std::vector<int> triStart;   // CSR: points of triangle t are triPoints[triStart[t] .. triStart[t+1]) (nTris + 1)
    std::vector<int> triPoints;  // its vertices, edge points and face points
    Eigen::VectorXd scale;       // penalty factor of each point (nPoints) [-]: 1, or scaleByMass's
    std::vector<int> triCut;     // the cut that made each triangle, -1 for none (nTris; empty: none)
    int points() const { return static_cast<int>(nodes.cols()); }
};

// How many points contactPoints would make, without making them (a bound checked up front).
double contactPointCount(const EmbeddedSurface& s, const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& X,
                         double spacing);

// Surface vertices, plus points on each edge and inside each face so that neighbours are at most
// `spacing` apart in the rest shape X (3 x nNodes) [m]; spacing <= 0: vertices only.
ContactPoints contactPoints(const EmbeddedSurface& s, const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& X,
                            double spacing);

// Penalty scaled by the effective mass of each point, m_p = 1 / (w_p^T M^-1 w_p) (free nodes; a
// point on fixed nodes only is infinitely heavy): scale_p = min(1, m_p / mRef), so a tool's
// stiffness k and damping c act in full on points of mass >= mRef and as k m_p / mRef below, the
// same contact frequency sqrt(k / mRef) everywhere (the idea of explicit codes' soft-constraint
// contact, penalty from nodal mass). Light points, e.g. on the small inside shares of MI interface
// elements, then no longer set the stiffness limit for all (BENCHMARKS.md, Contact).
void scaleByMass(ContactPoints& pts, const Eigen::VectorXd& invMass, double mRef);
// mRef of a surface: the 90th percentile of its points' effective masses (finite ones) [kg].
double referenceMass(const ContactPoints& pts, const Eigen::VectorXd& invMass);

// Largest penalty stiffness per contact point [N/m] that keeps an explicit step dt stable on
// `model`, whose exact limit is dtCrit (docs/method.md sec. 2: lambda_max(M^-1 K_total) <= (2/dt)^2).
// Contact adds K_p = sum_p k s_p w_p w_p^T (x) n_p n_p^T for the points in contact
// (s_p = pts.scale), and K_p <= k C with C = sum_p s_p w_p w_p^T (x) I over ALL points (every point
// in contact, any normal), so the step stays stable while
// lambda_max(M^-1/2 (K + k C) M^-1/2) <= (2/dt)^2, i.e. k <= 1 / nu_max of the pencil
// C x = nu ((2/dt)^2 I - M^-1/2 K M^-1/2) x (positive definite for dt < dtCrit), solved exactly
// by Lanczos (Spectra, Cholesky mode) on the rest stiffness as the exact step is.
// Exact and joint, because the contact's top modes sit on light embedded nodes whose elastic
// stiffness is as small as their mass, not on the top elastic mode: Weyl's sum of the two
// eigenvalues is several times too pessimistic there (BENCHMARKS.md, Contact).
// Returns 0 when dt >= dtCrit (no headroom left), infinity when no point moves a free node.
// Throws EigenSolveError when Lanczos does not converge.
double stableStiffness(const ContactPoints& pts, const Model& model, double dt, double dtCrit);
// A tool's default stiffness as a fraction of that limit. The limit certifies the linearised
// (bilateral) penalty; real contact switches on and off, and a point entering and leaving the
// tool on alternate steps gains energy near the limit (tests/contact/contact_test.cpp).
inline constexpr double kDefaultStiffnessFraction = 0.5;

// Gauss-Seidel sweeps of the projection over its contacts (velocities, then positions), at most;
// they stop after a sweep that changed no contact's velocity by more than kSettledSpeed [m/s] (or
// its position by more than kSettledMove [m]).
inline constexpr int kProjectionIterations = 8;
inline constexpr double kSettledSpeed = 1e-9;
inline constexpr double kSettledMove = 1e-12;

// What contact did in the last step.
struct ContactStep {
    std::vector<Eigen::Vector3d> reaction;  // force of the tissue on each tool (nTools) [N]
    int contacts = 0;                       // points inside a tool [-]
    int colliderContacts = 0;               // points inside a collider [-]
    int pieceContacts = 0;                  // points of one piece inside another (projection only) [-]
    double maxDepth = 0;                    // deepest point inside a tool, before projection [m] (*)
    double colliderDepth = 0;               // deepest point inside a collider, before projection [m] (*)
    // (*) a point the projection holds by its nodes inside the material alone is measured there
    double residualDepth = 0;  // deepest left after the projection [m]
    int tested = 0;            // points whose distance to a shape was computed [-]
};

// Signed distance of the world point x to one part of `tool` whose frame is `frame` [m]
// (negative inside), n the unit way out: in closed form for spheres, capsules and boxes, by
// Bullet's GJK/EPA for hulls or when closedForm is false.
double partSignedDistance(const ToolPart& part, const ToolDef& tool, const Pose& frame, const Eigen::Vector3d& x,
                          Eigen::Vector3d& n, bool closedForm = true);

class ContactWorld {
public:
    explicit ContactWorld(std::vector<ToolDef> tools, std::vector<ColliderDef> colliders = {});
    ~ContactWorld();
    ContactWorld(const ContactWorld&) = delete;
    ContactWorld& operator=(const ContactWorld&) = delete;

    // (Re)builds the contact points, e.g. after a cut changed the surface. `rest`: the mesh's rest
    // positions (3 x nNodes) [m], needed for contact between pieces (null: none). `outside`: nodes
    // that lie outside the material (nNodes, 1 = outside; empty: none), as a cut's virtual nodes do
    // (CutEngine::virtualNodes); the projection corrects a point through its other nodes when they
    // carry kMinFreeWeight of it.
    void setSurface(ContactPoints pts, const Eigen::Matrix3Xd* rest = nullptr, std::vector<std::uint8_t> outside = {});
    // The points on these nodes take no contact until the next setSurface: a blade step split the
    // elements they lie in, so their nodes now span the cut (the surface is rebuilt later).
    void dropPoints(const std::vector<int>& nodes);
    // Tool `tool` no longer touches the faces cut `cut` made (-1: touches all). A blade slides in
    // its own cut: those faces lie within its thickness, and pressing them apart puts force
    // spikes on the tissue. Their points that also lie on other faces (the cut's rim) are still
    // touched.
    void ignoreCut(int tool, int cut);
    // The slot tool `tool` has cut: the area its edge swept in the plane through `origin` with unit
    // axes u, v (normal u x v), as convex polygons in (u, v) [m]. The model's crack has no
    // thickness, so the blade does not touch the points within `halfWidth` of that plane whose
    // projection lies in the swept area: it slides in its cut. Without this its faces push every
    // point that a cut leaves inside the blade's thickness out sideways in one step, up to half
    // the thickness, which on elements of a few blade thicknesses is a strain of tens of percent
    // and drove the fine meshes' cut regions unstable (docs/method.md, Contact). Empty polygons: none.
    struct Slot {
        Eigen::Vector3d origin = Eigen::Vector3d::Zero(), u = Eigen::Vector3d::UnitX(), v = Eigen::Vector3d::UnitY();
        double halfWidth = 0;                                // [m]
        std::vector<std::vector<Eigen::Vector2d>> polygons;  // convex, (u, v) [m]
        bool contains(const Eigen::Vector3d& x) const;
    };
    void setSlot(int tool, Slot slot);
    const ContactPoints& points() const;

    // Contact forces at node positions x and velocities v (3 x nNodes) at time t, added into f
    // (3 x nNodes) [N]; dt is the step, for the tool's velocity over it. Fills last().
    void addForces(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double t, double dt, Eigen::Matrix3Xd& f);
    // Kinematic contact after the step that ended at `time` (of length dt): positions x and
    // velocities v (3 x nNodes) of the points inside a tool or collider are corrected in place
    // (invMass: nNodes [1/kg], 0 for fixed nodes). Fills last(); the reaction is the momentum
    // given over dt.
    // moved, when given: the nodes the projection moved, sorted (Stepper::repairInverted).
    void project(const Eigen::VectorXd& invMass, double time, double dt, Eigen::Matrix3Xd& x, Eigen::Matrix3Xd& v,
                 std::vector<int>* moved = nullptr);
    const ContactStep& last() const;
    // Separated pieces of the surface (joined by no node) touch each other, with Coulomb friction
    // (project only; off by default). Pieces: connected parts of the current surface.
    void setPieceContact(bool on, double friction);
    int pieces() const;
    // Penalty stiffness and damping of every collider (addForces only) [N/m], [N s/m].
    void setColliderPenalty(double stiffness, double damping);

    std::vector<ToolDef>& tools();
    const std::vector<ToolDef>& tools() const;
    const std::vector<ColliderDef>& colliders() const;

    // Bullet worlds alive in this process (a scene without tools must leave it at 0).
    static int live();

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace cutsim
