// What the renderer sees of a simulation at one capture frame: plain data filled by physics, no GL.
// render/ reads only this struct, so physics and render stay independent (README.md, data flow).
#pragma once

#include "contact/tool_shape.hpp"
#include "mesh/embedding.hpp"
#include "mesh/mesh.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace cutsim {

// A perspective camera.
struct Camera {
    Eigen::Vector3d eye{0, 0, 1};     // [m]
    Eigen::Vector3d target{0, 0, 0};  // point at the screen centre [m]
    Eigen::Vector3d up{0, 1, 0};      // world direction shown as up on screen (also the floor normal)
    double fovY = 40;                 // vertical field of view [deg]
};

// The floor grid: the plane of points p with p . normal = height, drawn as a square grid.
// Set once from the scene so it stays put while pieces fall (a plane collider can set it too).
struct Floor {
    bool fixed = false;                                // false: just under each frame's lowest surface point,
                                                       // sized to the frame, normal = camera.up
    Eigen::Vector3d normal{0, 0, 1};                   // unit normal, pointing up
    double height = 0;                                 // offset along normal [m]
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // grid centre, projected onto the plane [m]
    double spacing = 0.01;                             // grid line spacing [m]
    double halfSize = 0.05;                            // half the grid's side [m]
};

// Values the HUD shows; every time in seconds.
struct HudValues {
    bool simulated = true;                                      // false: a still mesh, no time, step or count lines
    double simTime = 0;                                         // simulated time [s]
    double dtUsed = 0;                                          // time step used [s]
    double dtCertified = 0;                                     // certified stable time step [s]
    double dtExact = std::numeric_limits<double>::quiet_NaN();  // exact stable step [s]; NaN when unknown
    double stepsPerSecond = 0;                                  // wall-clock steps per second [1/s]
    double realTimeFactor = 0;                                  // simulated seconds per wall-clock second [-]
    int criticalElements = 0;                                   // elements that limit the time step [-]
    double criticalStep = std::numeric_limits<double>::quiet_NaN();  // the step the drawn critical elements
                                                                     // would allow (their smallest estimate) [s]
    int cuts = 0;                                                    // cuts applied so far [-]
    int answeredElements = 0;        // elements a recent cut made critical that the step policy answered [-]
    std::vector<std::string> lines;  // free text, one entry per line
    std::vector<float> forcePlot;    // recent tool force magnitudes, oldest first [N]; plotted when not empty
};

// Everything one frame draws.
struct RenderSnapshot {
    // Surface
    Eigen::Matrix3Xd positions;         // surface vertex positions (3 x nVerts) [m]
    Eigen::Matrix3Xd normals;           // unit vertex normals (3 x nVerts), or empty: the renderer computes
                                        // area-weighted normals
    Eigen::Matrix3Xi triangles;         // vertex indices, counter-clockwise seen from outside (3 x nTris)
    std::vector<std::uint8_t> cutFace;  // 1 = face created by a cut, drawn in its own colour (nTris), or empty

    // Colour map
    Eigen::VectorXd scalar;  // per-vertex value mapped to colour (nVerts), or empty: plain colour
    std::string scalarName;  // legend title, e.g. "volume"
    std::string scalarUnit;  // legend unit, e.g. "m^3"
    double scalarMin = 0;    // value at the low end of the map [scalarUnit]
    double scalarMax = 1;    // value at the high end of the map [scalarUnit]
    bool diverging = false;  // diverging map (blue-white-red) instead of sequential (viridis)

    // Overlays
    Eigen::Matrix3Xd edges;         // wireframe segments, endpoints in pairs (3 x 2*nEdges) [m], or empty
    Eigen::Matrix3Xd criticalTets;  // critical elements, 4 corners each (3 x 4*nCritical) [m]; drawn
                                    // through the surface (x-ray)
    Eigen::Matrix3Xd answeredTets;  // elements a recent cut made critical and the step policy answered,
                                    // 4 corners each [m]; outlined through the surface
    std::vector<ToolShape> tools;

    Camera camera;
    Floor floor;
    HudValues hud;

    int vertices() const { return static_cast<int>(positions.cols()); }
    int faces() const { return static_cast<int>(triangles.cols()); }
};

// A snapshot of a tet mesh with the surface it keeps, so later frames only move vertices.
struct MeshSnapshot {
    RenderSnapshot snap;
    EmbeddedSurface surface;  // where each surface vertex rides in the mesh
};

// Options of snapshotFromTetMesh.
struct MeshSnapshotOptions {
    const Eigen::VectorXd* elementValues = nullptr;  // per-element scalar (nElems), or null: no colour map
    std::string name;                                // scalar name for the legend
    std::string unit;                                // scalar unit for the legend
    bool diverging = false;                          // use the diverging map (symmetric range around 0)
    bool wireframe = false;                          // add every tet edge as a wireframe segment
    std::vector<int> critical;                       // elements to draw in x-ray
};

// Builds a snapshot of mesh at node positions x (3 x nNodes) [m]: the boundary surface
// (boundaryFaces), per-vertex values as the mean over the elements around each node, and a
// camera framing the bounding box.
MeshSnapshot snapshotFromTetMesh(const TetMesh& mesh, const Eigen::Matrix3Xd& x, const MeshSnapshotOptions& opts = {});
MeshSnapshot snapshotFromTetMesh(const TetMesh& mesh, const MeshSnapshotOptions& opts = {});

// The same for a given embedded surface (a cut or embedded object) instead of the boundary faces.
MeshSnapshot snapshotFromSurface(const TetMesh& mesh, const Eigen::Matrix3Xd& x, EmbeddedSurface surface,
                                 const MeshSnapshotOptions& opts = {});

// Sets the per-vertex scalar, legend and range from opts.elementValues (mean over the elements
// around the node each surface vertex follows most); nothing when it is null. For fields that change between frames.
void setElementValues(MeshSnapshot& ms, const TetMesh& mesh, const MeshSnapshotOptions& opts);

// Moves the surface (and wireframe, critical tets) of a snapshot to new node positions.
void updateSnapshotPositions(MeshSnapshot& ms, const TetMesh& mesh, const Eigen::Matrix3Xd& x,
                             const MeshSnapshotOptions& opts = {});

// Largest of 1, 2, 5 times a power of ten not above x (grid and tick spacing).
double niceGridStep(double x);

// A camera looking at the box [lo, hi] from the front-right and above, the whole box in view
// for an aspect ratio (width / height) of at least 1.
Camera frameBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, const Eigen::Vector3d& up = {0, 0, 1});

}  // namespace cutsim
