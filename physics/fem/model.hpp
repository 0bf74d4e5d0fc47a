// The fixed part of a simulation: rest shape, elements, masses, material, boundary conditions.
// Changes only at a topology change (a cut); the per-step data lives in State (fem/state.hpp).
#pragma once

#include "fem/material.hpp"
#include "mesh/mesh.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <cstdint>
#include <span>
#include <vector>

namespace cutsim {

enum class ElementModel : std::uint8_t { Linear, Corotational };

// Arithmetic of the element force kernel (fem/forces.cpp). Positions, velocities, node sums and
// every other stage stay double; Single runs the element's F, rotation and stress in float on
// twice the lanes. Its force error relative to the element's stress is ~6e-8 / strain (float's
// rounding of F ~ I). Meant for the explicit schemes: a backward-Euler step spends under 2% of its
// time in this kernel, so it would gain nothing there.
enum class ForcePrecision : std::uint8_t { Double, Single };

struct Model {
    Material material;
    ElementModel elementModel = ElementModel::Corotational;
    ForcePrecision precision = ForcePrecision::Double;

    // Nodes
    Eigen::Matrix3Xd X;               // rest positions (3 x nNodes) [m]
    Eigen::VectorXd mass;             // lumped nodal mass, row-sum lumping (nNodes) [kg]
    Eigen::VectorXd addedMass;        // mass added to keep a target step, included in mass
                                      // (timestep/timestep.hpp keepStep; nNodes, or empty) [kg]
    Eigen::VectorXd invMass;          // 1/mass; 0 for fixed or massless nodes (nNodes) [1/kg]
    std::vector<std::uint8_t> fixed;  // 1 = position prescribed (nNodes)

    // Elements
    Eigen::Matrix4Xi tets;                           // node indices (4 x nElems)
    Eigen::Matrix<double, 9, Eigen::Dynamic> DmInv;  // inverse rest shape matrix, column-major (9 x nElems,
                                                     // more columns after cuts: capacity) [1/m]
    Eigen::VectorXd volume;                          // rest volume of the (parent) element (nElems) [m^3]
    Eigen::VectorXd fraction;                        // share of the volume this element stands for (nElems) [-];
                                                     // 1 for an ordinary element, < 1 for a virtual element of a cut
    Eigen::Matrix4Xd massShare;                      // share of rho * volume lumped to each corner (4 x nElems) [-],
                                                     // or empty: fraction / 4 each (set by the cut's lumping option)

    // Loads and damping
    Eigen::Vector3d gravity = Eigen::Vector3d::Zero();  // [m/s^2]
    double massDamping = 0;                             // mass-proportional damping coefficient [1/s]

    // Free nodes with a few percent of their node's mass, whose velocity relative to the nodes
    // they share elements with is damped implicitly (c = 0.5/dt) by the symplectic Euler and
    // central difference steps: control points a cut left light, and MI lattice nodes of nearly
    // empty cells (CutOptions::lightShare of wholeMass). Empty for an uncut conforming model.
    std::vector<int> lightNodes;

    // Hybrid elements (Fierz et al. 2012; timestep/hybrid.hpp): moved by shape matching (Mueller et
    // al. 2005) after each explicit step instead of by FEM forces, so their stiffness leaves K, the
    // force stage and the step's limit (nElems or shorter; missing entries are 0). Empty: none.
    std::vector<std::uint8_t> matched;
    std::vector<int> matchedList;  // the elements with matched[e] = 1, ascending
    double matchStiffness = 1;     // shape matching's alpha in (0, 1]: share of the way to the goal per step

    bool isMatched(int e) const { return static_cast<size_t>(e) < matched.size() && matched[static_cast<size_t>(e)]; }
    // V fraction for the stiffness: 0 for a matched element.
    double stiffnessVolume(int e) const { return isMatched(e) ? 0.0 : volume(e) * fraction(e); }

    // Node -> incident element slots: slot s = 4*e + a means local node a of element e; node i's
    // slots are nodeSlots[nodeSlotStart[i], nodeSlotEnd[i]), in ascending element order
    // (computeForces sums in it and finds the nodes two threads share from the first and last).
    // Built in node order; a cut rewrites its rows in place or moves them to the end, leaving
    // gaps until the next rebuild (updateIncidence).
    std::vector<int> nodeSlotStart;  // (nNodes)
    std::vector<int> nodeSlotEnd;    // (nNodes)
    std::vector<int> nodeSlots;      // (4 * nElems, plus gaps)
    std::span<const int> slotsOf(int i) const {
        return {nodeSlots.data() + nodeSlotStart[static_cast<size_t>(i)],
                nodeSlots.data() + nodeSlotEnd[static_cast<size_t>(i)]};
    }

    int nodes() const { return static_cast<int>(X.cols()); }
    int elements() const { return static_cast<int>(tets.cols()); }
    int freeDofs() const;
    Eigen::Matrix3d dmInv(int e) const { return Eigen::Map<const Eigen::Matrix3d>(DmInv.col(e).data()); }
};

// Builds a model from a mesh. Throws InputError for a zero-volume or inverted element.
Model buildModel(const TetMesh& mesh, const Material& material, ElementModel elementModel = ElementModel::Corotational);

// Recomputes lumped masses (rho V fraction / 4 per node, or rho V massShare, plus addedMass) and
// inverse masses; call after changing fixed nodes, fractions or the material.
void updateMasses(Model& model);
// The same for `nodes` only, the others kept: each sum gathered over the incidence (current:
// updateIncidence first) in ascending element order, the order updateMasses adds in, so the
// values are the same bit for bit. Nodes appended since the last update must be among `nodes`.
void updateMasses(Model& model, const std::vector<int>& nodes);
// Lumped mass of each node as if its elements were whole (fraction 1, no added mass) [kg]: the
// reference against which a node of partial elements counts as light (Model::lightNodes).
Eigen::VectorXd wholeMass(const Model& model);

// Sets Model::lightNodes: the free nodes with less than `share` of their reference mass,
// reference(originalOf[n]) (reference(n) without originalOf), e.g. wholeMass. share <= 0: none.
void markLightNodes(Model& model, const Eigen::VectorXd& reference, double share,
                    const std::vector<int>* originalOf = nullptr);

// Marks nodes as fixed (their inverse mass becomes 0).
void fixNodes(Model& model, const std::vector<int>& nodes);

// Rebuilds the node -> element incidence after elements changed.
void buildIncidence(Model& model);
// The same after a local change: `elements` are the appended elements and every element whose
// corners changed; `rows` every node that gained or lost a corner of them (appended nodes
// included). Only those rows are written (in place, or at the end when they grew), so a cut
// costs what it changed; the slots are rebuilt when gaps outgrow half the live ones.
void updateIncidence(Model& model, const std::vector<int>& rows, const std::vector<int>& elements);

// Assembled rest stiffness K (3n x 3n), each element scaled by its fraction. DOF 3i+k.
Eigen::SparseMatrix<double> assembleStiffness(const Model& model);

// Free-DOF numbering: global DOF 3i+k -> its index among the free DOFs (invMass > 0), or -1;
// a free node's three DOFs are consecutive. *nFree gets their number.
std::vector<int> freeDofMap(const Model& model, int* nFree);
// K restricted to the free DOFs of `map` (nf of them), optionally scaled to diag(s) K diag(s).
Eigen::SparseMatrix<double> freeStiffness(const Model& model, const std::vector<int>& map, int nf,
                                          const Eigen::VectorXd* scale = nullptr);
// M^-1/2 K M^-1/2 over the free DOFs (the operator of the exact step, thesis eq. 3.10).
Eigen::SparseMatrix<double> scaledFreeStiffness(const Model& model, const std::vector<int>& map, int nf);

// Connected pieces of elements joined through shared nodes: their volumes (V fraction), largest
// first [m^3].
std::vector<double> pieceVolumes(const Model& model);

// The mesh this model was built from (rest positions), e.g. for output.
TetMesh restMesh(const Model& model);

// Nodes all of whose elements stand for part of their volume (fraction < 1), e.g. a cut's virtual
// nodes and an MI lattice's outside nodes (nNodes, 1 = such a node). Empty when every element is
// whole.
std::vector<std::uint8_t> partialNodes(const Model& model);
// Whether any element holds less than its whole tet (fraction < 1). Searched from the end, where a
// cut appends its virtual elements, so a cut model answers at once instead of in a pass.
bool anyPartial(const Model& model);

}  // namespace cutsim
