// Tool-tissue contact through Bullet. Created only when a scene has tools (DESIGN.md: no Bullet
// world without a tool).
//
// Representation, chosen by measured cost (tests/bench/contact_bench.cpp: the liver, 5494 contact
// points, one probe 3 mm deep; CPU time per step on a shared 2-core machine): the surface is a
// cloud of contact points (its vertices plus points on its edges and faces, at most `spacing`
// apart). A btDbvt over triangle boxes, refitted every step with a fat margin, is queried with
// each tool part's box (from the btCollisionWorld's broad phase); the candidate triangles' points
// get their signed distance to the tool's convex core from Bullet's GJK/EPA
// (btGjkEpaSolver2::SignedDistance, as Bullet's soft-body nodes do against rigid bodies). Only
// vertices are interpolated every step, other points when their triangle is a candidate:
// ~12 us. Every point a collision object in the btCollisionWorld costs ~190 ms (the pair cache
// over thousands of proxies), and a refitted btBvhTriangleMeshShape ~50 us for at most 4
// manifold points and no depth for points already inside the tool.
//
// Forces: penalty f = s_p max(0, k d - c v_n) n per point inside a tool (s_p its mass scale,
// scaleByMass; d depth, n the way out, v_n the separating speed relative to the tool), spread to
// the mesh nodes by the transpose of the interpolation x_p = sum_i w_i x_i, so it works the same
// for cut faces and embedded (MI) surfaces.
// The reaction on each tool is minus the sum of its point forces.
#pragma once

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
    Eigen::Matrix<int, kMaxNodes, Eigen::Dynamic> nodes;      // node indices (12 x nPoints); unused slots: node 0
    Eigen::Matrix<double, kMaxNodes, Eigen::Dynamic> weights; // interpolation weights (12 x nPoints) [-]; unused: 0
    std::vector<std::uint8_t> count;                           // used slots of each point, packed first (nPoints)
    Eigen::Matrix3Xi triangles;   // surface triangles as vertex point indices (3 x nTris)
    std::vector<int> triStart;    // CSR: points of triangle t are triPoints[triStart[t] .. triStart[t+1]) (nTris + 1)
    std::vector<int> triPoints;   // its vertices, edge points and face points
    Eigen::VectorXd scale;        // penalty factor of each point (nPoints) [-]: 1, or scaleByMass's
    std::vector<int> triCut;      // the cut that made each triangle, -1 for none (nTris; empty: none)
    int points() const { return static_cast<int>(nodes.cols()); }
};

// Surface vertices, plus points on each edge and inside each face so that neighbours are at most
// `spacing` apart in the rest shape X (3 x nNodes) [m]; spacing <= 0: vertices only.
ContactPoints contactPoints(const EmbeddedSurface& s, const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& X,
                            double spacing);

// Penalty scaled by the effective mass of each point, m_p = 1 / (w_p^T M^-1 w_p) (free nodes; a
// point on fixed nodes only is infinitely heavy): scale_p = min(1, m_p / mRef), so a tool's
// stiffness k and damping c act in full on points of mass >= mRef and as k m_p / mRef below, the
// same contact frequency sqrt(k / mRef) everywhere (the idea of explicit codes' soft-constraint
// contact, penalty from nodal mass). Light points, e.g. on the small inside shares of MI interface
// elements, no longer set the limit for all: on the demo liver at dt = 0.9 dtCrit the stiffness
// under the probe (sum of k scale_p over the points within 1 cm of its first touch) rises from 245
// to 902 N/m on MI (8 cells) and from 3.5e3 to 1.55e4 N/m conforming.
void scaleByMass(ContactPoints& pts, const Eigen::VectorXd& invMass, double mRef);
// mRef of a surface: the 90th percentile of its points' effective masses (finite ones) [kg].
double referenceMass(const ContactPoints& pts, const Eigen::VectorXd& invMass);

// Largest penalty stiffness per contact point [N/m] that keeps an explicit step dt stable on
// `model`, whose exact limit is dtCrit (METHOD.md sec. 2: lambda_max(M^-1 K_total) <= (2/dt)^2).
// Contact adds K_p = sum_p k s_p w_p w_p^T (x) n_p n_p^T for the points in contact (s_p = pts.scale),
// and K_p <= k C with C = sum_p s_p w_p w_p^T (x) I over ALL points (every point in contact, any normal), so the step stays
// stable while lambda_max(M^-1/2 (K + k C) M^-1/2) <= (2/dt)^2, i.e. k <= 1 / nu_max of the pencil
// C x = nu ((2/dt)^2 I - M^-1/2 K M^-1/2) x (positive definite for dt < dtCrit), solved exactly by
// Lanczos (Spectra, Cholesky mode) on the rest stiffness as the exact step is.
// Why exact and joint, measured on the demo liver at dt = 0.9 dtCrit, unscaled points: the
// former bound, Weyl's lambda_max(M^-1 K) + ||M^-1/2 k C M^-1/2|| with block Gershgorin on the
// second term, gave 43.4 N/m conforming and 1.31 N/m MI (8 cells); the exact C-norm in Weyl's sum
// 48.5 / 2.61; the joint value 92.1 / 6.41: the contact's top modes sit on light embedded nodes
// whose elastic stiffness is as small as their mass, not on the top elastic mode. Restricting C to
// the patch one tool can touch gained another ~2x on MI but needs the touched set in rest
// coordinates, which deformation does not bound, so it is not used.
// Returns 0 when dt >= dtCrit (no headroom left), infinity when no point moves a free node.
// Throws EigenSolveError when Lanczos does not converge.
double stableStiffness(const ContactPoints& pts, const Model& model, double dt, double dtCrit);
// A tool's default stiffness as a fraction of that limit. The limit certifies the linearised
// (bilateral) penalty; real contact switches on and off, and when its mode is near the limit a
// point entering and leaving the tool on alternate steps gains energy: on an MI slab pressed over
// its whole face (tests/contact/contact_test.cpp) the points stay within 3.1 mm of a 1 mm press
// at 0.5 x the limit, 9.5 mm at 0.6 x, 0.54 m at 1.0 x (1500 steps).
inline constexpr double kDefaultStiffnessFraction = 0.5;

// What contact did in the last step.
struct ContactStep {
    std::vector<Eigen::Vector3d> reaction; // force of the tissue on each tool (nTools) [N]
    int contacts = 0;                      // points inside a tool [-]
    double maxDepth = 0;                   // deepest point inside a tool [m]
};

class ContactWorld {
public:
    explicit ContactWorld(std::vector<ToolDef> tools);
    ~ContactWorld();
    ContactWorld(const ContactWorld&) = delete;
    ContactWorld& operator=(const ContactWorld&) = delete;

    // (Re)builds the contact points, e.g. after a cut changed the surface.
    void setSurface(ContactPoints pts);
    // Tool `tool` no longer touches the faces cut `cut` made (-1: touches all). A blade slides in
    // its own cut: its faces lie in the blade's mid-plane, within its thickness, and pressing them
    // apart by half that thickness put spikes of up to 344 N on a 0.6 kg liver (blade.json). Their
    // points that also lie on other faces (the cut's rim) are still touched.
    void ignoreCut(int tool, int cut);
    const ContactPoints& points() const;

    // Contact forces at node positions x and velocities v (3 x nNodes) at time t, added into f
    // (3 x nNodes) [N]; dt is the step, for the tool's velocity over it. Fills last().
    void addForces(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double t, double dt, Eigen::Matrix3Xd& f);
    const ContactStep& last() const;

    std::vector<ToolDef>& tools();
    const std::vector<ToolDef>& tools() const;

    // Bullet worlds alive in this process (a scene without tools must leave it at 0).
    static int live();

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

} // namespace cutsim
