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
// Forces: penalty f = max(0, k d - c v_n) n per point inside a tool (d depth, n the way out, v_n
// the separating speed relative to the tool), spread to the mesh nodes by the transpose of the
// interpolation x_p = sum_i w_i x_i, so it works the same for cut faces and embedded (MI) surfaces.
// The reaction on each tool is minus the sum of its point forces.
#pragma once

#include "contact/tool.hpp"
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
    int points() const { return static_cast<int>(nodes.cols()); }
};

// Surface vertices, plus points on each edge and inside each face so that neighbours are at most
// `spacing` apart in the rest shape X (3 x nNodes) [m]; spacing <= 0: vertices only.
ContactPoints contactPoints(const EmbeddedSurface& s, const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& X,
                            double spacing);

// Largest penalty stiffness per contact point [N/m] that keeps an explicit step dt stable on a
// model whose exact limit is dtCrit. With every point in contact the penalty adds K_p =
// sum_p k (w_p w_p^T) (x) (n n^T) to the stiffness; by Weyl's inequality lambda_max(M^-1(K + K_p))
// <= lambda_max(M^-1 K) + ||M^-1/2 K_p M^-1/2||, and block Gershgorin bounds the second term by
// k max_a sum_p w_pa sum_b w_pb / sqrt(m_a m_b) (free nodes). The step stays stable while the sum
// is below (2/dt)^2 (METHOD.md sec. 2), so k <= ((2/dt)^2 - (2/dtCrit)^2) / that maximum.
// Returns 0 when dt >= dtCrit (no headroom left).
double stableStiffness(const ContactPoints& pts, const Eigen::VectorXd& invMass, double dt, double dtCrit);

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
