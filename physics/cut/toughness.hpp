// Cutting that takes force: a blade's edge advances into tissue of fracture toughness G_c only
// when it pays G_c for each unit of area it cuts (material.toughness; docs/method.md, "Tissue
// toughness"). Mahvash and Hayward (2004) describe the three phases a cutting tool goes through:
// deformation (the edge presses, the tissue stores energy), rupture (a crack starts) and steady
// cutting (the work of the tool pays the fracture energy).
//
// The model: the material at the crack front is a line of points (the front points, embedded in
// the elements just ahead of the front with barycentric weights) that the blade's edge may not
// pass. While the force this takes stays below G_c times the length of the front in the material,
// the points stick to the edge and are pushed with it (projection, as contact pushes the surface):
// the tissue deforms (pressing). A step whose force would exceed that cap slides: the front
// points get the capped impulse only, the edge passes them, and the front advances to the edge;
// the cut engine then sweeps the area from the old front to the new one. Griffith's criterion for
// a rigid edge pressing the crack tip of a body whose deformation travels with the tip: the energy
// released per unit of crack advance at a fixed edge is the force on the edge (load-point
// compliance argument), so G = F / b and the crack grows when F >= G_c b. Where the compliance
// falls as the crack grows (a ligament under the edge relaxing as the cut shortens it), material
// comes up to the edge faster than the edge moves and G_c b does not pay for its crack: the front
// keeps an account of the energy balance over the stroke (the blades' work less the stored,
// kinetic and damped energy, against G_c times the area cut) and raises the cap while it is in
// debt.
#pragma once

#include "cut/xfem.hpp"
#include "fem/model.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

namespace cutsim {

enum class CutPhase : std::uint8_t { Idle, Pressing, Cutting };
using VirtualNodeTest = std::function<bool(int)>;  // node -> virtual (CutEngine::isVirtualNode)
const char* cutPhaseName(CutPhase p);              // idle | pressing | cutting

class BladeToughness {
public:
    // gc: fracture toughness [J/m^2] (> 0); samples: front points along the blade's edge; rate:
    // samples per second of the force series [1/s].
    BladeToughness(double gc, int samples, double rate);
    double toughness() const { return gc_; }

    // Blade stage, for the blade whose stroke is open, at the step's start: the edges the cut
    // engine sweeps this step. Without a front yet, one is seeded where the blade's edge `now`
    // (cutting direction `dir`, unit) lies in the material (elements `candidates`, nodes at x;
    // `isVirtual` as CutEngine::isVirtualNode, asked only when seeding). Returns true when the front
    // advanced in the last step: then from, to are the old and the new front (the first advance
    // starts behind the elements the seed points lie in, so the engine covers their whole
    // cross-section).
    bool sweepEdges(const Model& m, const Eigen::Matrix3Xd& x, const BladeEdge& now, const Eigen::Vector3d& dir,
                    const std::vector<int>& candidates, const VirtualNodeTest& isVirtual, BladeEdge& from,
                    BladeEdge& to);
    // After the engine swept to the new front: its points, in the elements ahead of it.
    void reseed(const Model& m, const Eigen::Matrix3Xd& x, const Eigen::Vector3d& dir,
                const std::vector<int>& candidates, const VirtualNodeTest& isVirtual);
    // After the step's integration, before contact: the edge `edge` at the step's end presses the
    // front points (velocities, then positions, or the capped impulse and an advance); m the
    // model (masses, rest shapes); dt the step [s].
    // stored: the elastic, kinetic and gravitational energy now and the energy damping took in the
    // step [J], asked only in some of the steps whose front force reaches G_c b.
    void project(const Model& m, double dt, const BladeEdge& edge, const Eigen::Vector3d& dir,
                 const std::function<double()>& stored, Eigen::Matrix3Xd& x, Eigen::Matrix3Xd& v);
    // The force of the tissue on the blade through its front in the last step [N].
    const Eigen::Vector3d& reaction() const { return reaction_; }
    CutPhase phase() const { return phase_; }
    // The phase over the last `window` seconds before `now`: cutting when the front advanced in
    // any step of it (steady cutting alternates pressing and cutting steps), else phase().
    CutPhase phaseOver(double now, double window) const;
    bool hasFront() const { return !points_.empty(); }
    void endStroke();  // the front is forgotten; the next stroke seeds its own

    // Bookkeeping of the step [t, t + dt] (after contact): the work the blades did on the tissue
    // `work` [J], the cutting blade's force along its cutting direction `along` [N] (contact and
    // front), the energy mass damping took `damped` [J].
    void record(double t, double dt, long step, double work, double along, double damped);
    double work() const { return work_; }            // blade work on the tissue [J]
    double cutArea() const { return area_; }         // area paid for [m^2]
    double fracture() const { return gc_ * area_; }  // [J]
    double damping() const { return damped_; }       // [J]
    // report.json blade.toughness; energies of the run's start and now [J] for the balance.
    nlohmann::json report(double elastic0, double kinetic0, double gravity0, double elastic, double kinetic,
                          double gravity) const;

private:
    struct Point {
        int element = -1;
        std::array<int, 4> node{};
        Eigen::Vector4d w = Eigen::Vector4d::Zero();
        double length = 0;  // edge length it stands for [m]
        double mass = 0, lambda = 0, push = 0, pen = 0, c0 = 0;
    };
    void advanceRest(double sampleLength);
    int seed(const Model& m, const Eigen::Matrix3Xd& x, const BladeEdge& edge, const Eigen::Vector3d& dir,
             const std::vector<int>& candidates, const VirtualNodeTest& isVirtual, double* reach);

    double gc_;
    int samples_;
    std::vector<Point> points_;
    Eigen::Vector3d dir_ = Eigen::Vector3d::Zero();  // cutting direction of the last projection
    BladeEdge front_;                                // where the engine swept to (or the seed's start) [m]
    BladeEdge target_;                               // the edge the front advanced to in the last step [m]
    bool advanced_ = false;                          // the last step slid: the engine owes the sweep front_ -> target_
    Eigen::Vector3d reaction_ = Eigen::Vector3d::Zero();
    CutPhase phase_ = CutPhase::Idle;
    double stepArea_ = 0;       // area the last advance cut [m^2]
    bool accountOpen_ = false;  // the stroke's edge has reached its front: accountStart_ is set
    double accountStart_ = 0;   // the energy balance then [J]
    double debt_ = 0;           // G_c times the area cut less the energy the balance left for it [J]
    long accountAge_ = 0;       // steps whose front force reached G_c b since the account opened
    std::vector<double>
        sampleRest_;  // rest coordinate along dir of each edge sample's material at the last seed (NaN: none) [m]
    std::vector<double> frontRest_;  // the furthest each sample's front has reached [m]
    // ledger
    double work_ = 0, area_ = 0, damped_ = 0, peak_ = 0;
    long pressingSteps_ = 0, cuttingSteps_ = 0, crushedSteps_ = 0;
    struct Segment {
        CutPhase phase;
        long first, last;   // steps
        double start, end;  // [s]
    };
    std::vector<Segment> segments_;
    // series at the force rate: mean force along the cutting direction over each window
    double sampleDt_, nextSample_ = 0, window_ = 0, impulse_ = 0;
    std::vector<double> sTime_, sForce_, sArea_;
    std::vector<int> sPhase_;
};

}  // namespace cutsim
