// Conforming plane cut with node snapping: the subdivision baseline the XFEM cut is compared
// against (thesis sec. 5.2 and Table 6.1, docs/method.md sec. 5). Nodes near the plane are snapped onto
// it, crossed tets are split into tets that share the edge intersection points with their
// neighbours, and the nodes on the plane are duplicated so the two sides come apart. A bounded cut
// (ConformingOptions::limits, e.g. a notch) splits the same tets but opens only part of the plane.
#pragma once

#include "mesh/mesh.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace cutsim {

// An infinite cut plane; the positive side is the one the normal points to.
struct CutPlane {
    Eigen::Vector3d point = Eigen::Vector3d::Zero();    // a point on the plane [m]
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit normal [-]
};

// Which part of the cut mesh to return.
enum class KeepSide : std::uint8_t {
    Both,      // both sides, separated along the plane (nodes on it duplicated)
    Positive,  // only the tets on the normal's side (Table 6.1 keeps the top part)
    Negative,  // only the tets on the other side
};

struct ConformingOptions {
    double snapFraction = 0.1;        // snap a node when |distance| < snapFraction * mean length of its
                                      // incident edges (thesis sec. 6.2: 0.1); 0 disables snapping [-]
    double onPlaneTolerance = 1e-12;  // |distance| <= this * bounding-box diagonal counts as on the
                                      // plane, so no cut point lands on a node [-]
    KeepSide keep = KeepSide::Both;
    // A bounded cut (keep must be Both): the plane's tets are split as for the infinite plane, but a
    // node on it is duplicated only when it lies strictly (beyond onPlaneTolerance) on the positive
    // side of every limit, so the crack opens there alone and its front stays joined. Snapping is
    // the infinite plane's; a node snapped onto the plane is judged at its snapped position. Empty:
    // the whole plane opens. conformingCuts applies the limits to every plane.
    std::vector<CutPlane> limits;
};

struct ConformingReport {
    int nodes = 0;            // nodes of the result
    int tets = 0;             // tets of the result
    int snappedNodes = 0;     // nodes moved onto the plane
    int rejectedSnaps = 0;    // nodes within the threshold left in place because moving them would
                              // invert or flatten a tet not lying in the plane
    int collapsedTets = 0;    // tets flattened into the plane by snapping, removed (zero volume)
    int splitTets = 0;        // tets the plane crossed, each split into 2 to 6 tets
    int cutPoints = 0;        // new nodes where the plane crosses an edge
    int duplicatedNodes = 0;  // nodes on the plane copied for the negative side (KeepSide::Both;
                              // with limits, those inside them)
    double minVolume = 0;     // smallest tet volume of the result [m^3]
    double volumeBefore = 0;  // total volume of the input [m^3]
    double volumeAfter = 0;   // total volume of the result [m^3] (kept sides only)
};

struct ConformingResult {
    TetMesh mesh;
    std::vector<std::int8_t> side;  // side of each tet of mesh: +1 positive, -1 negative (nTets)
    ConformingReport report;
};

// Cuts mesh by the plane. Every tet of the result is positively oriented with a volume > 0; with
// nothing snapped the kept volume equals the input's (both sides) or the analytic part (one side)
// up to round-off. Throws InputError for a zero normal (the plane's or a limit's), or for limits
// with keep other than Both.
ConformingResult conformingCut(const TetMesh& mesh, const CutPlane& plane, const ConformingOptions& opts = {});

// Applies the planes one after the other (the four-plane liver cut of thesis sec. 5.2), each with
// opts; report is summed over the cuts (nodes, tets, minVolume and volumeAfter are the final ones).
ConformingResult conformingCuts(const TetMesh& mesh, const std::vector<CutPlane>& planes,
                                const ConformingOptions& opts = {});

// Connected pieces (tets sharing a node) and each tet's piece index (nTets), pieces numbered from 0.
int connectedPieces(const TetMesh& mesh, std::vector<int>* tetPiece = nullptr);

}  // namespace cutsim
