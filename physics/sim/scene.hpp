// The scene: one JSON format drives runs, tests, benchmarks and recordings (docs/scene-format.md).
#pragma once

#include "contact/collider.hpp"
#include "contact/tool.hpp"
#include "cut/xfem.hpp"
#include "fem/integrate.hpp"
#include "fem/material.hpp"
#include "fem/model.hpp"
#include "improve/improve.hpp"
#include "sim/step_policy.hpp"
#include "sim/tetra.hpp"

#include <nlohmann/json.hpp>

#include <Eigen/Core>

#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace cutsim {

// A set of nodes: inside a box, near a plane, inside a sphere, or listed.
struct Region {
    enum class Kind { Box, Plane, Sphere, Nodes } kind = Kind::Box;
    Eigen::Vector3d min = Eigen::Vector3d::Zero(), max = Eigen::Vector3d::Zero();  // box corners [m]
    Eigen::Vector3d point = Eigen::Vector3d::Zero();                               // plane point or sphere centre [m]
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();                             // plane normal (unit)
    double distance = 0;     // plane: |signed distance| <= distance [m]; sphere radius [m]
    std::vector<int> nodes;  // explicit node indices (0-based)
    std::string path;        // key path, for messages
    std::string file;        // scene file, for messages
};

// Time profile of a load: a factor on the force. constant: 1 from start on; ramp: 0 -> 1 over
// [start, end]; sine: sin(2 pi (t - start) / period) in [start, end] (in [-1, 1]); pulse: 1 in [start, end].
struct Profile {
    enum class Kind { Constant, Ramp, Sine, Pulse } kind = Kind::Constant;
    double start = 0, end = 1e300;  // [s]
    double period = 1;              // sine period [s]
    double at(double t) const;
};

struct ForceLoad {
    Region region;
    Eigen::Vector3d force = Eigen::Vector3d::Zero();  // total force, shared equally by the region's nodes [N]
    Profile profile;
};

// Divergence checks (Simulation, sim/simulation.hpp divergenceBounds): factors of the derived
// bounds, or bounds given outright (> 0).
struct Checks {
    double speedFactor = 10;         // speed bound in p-wave speeds (a strain of 10 at the wave front) [-]
    double displacementFactor = 10;  // displacement bound in object sizes [-]
    double maxSpeed = 0;             // > 0: the speed bound itself [m/s]
    double maxDisplacement = 0;      // > 0: the displacement bound itself [m]
    bool energy = true;              // check the energy when nothing does work
    double invertedFraction = 0.05;  // inverted elements (share of all, at least 10) that fail ...
    int invertedSteps = 100;         // ... when seen in this many steps in a row; 0: off
};

struct CameraKey {
    double time = 0;                                   // [s]
    Eigen::Vector3d eye = Eigen::Vector3d::Zero();     // [m]
    Eigen::Vector3d target = Eigen::Vector3d::Zero();  // [m]
    Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
    double fov = 40;  // vertical field of view [deg]
};

// `cutsim check`: how far a frame may be from its golden image (the renderdiff rule).
struct CheckSettings {
    int maxDiff = 5;            // a pixel fails when a channel differs by more than this [0, 255]
    double maxFailing = 0.001;  // a frame fails when more than this share of its pixels fail [-]
    std::vector<int> frames;    // frames to compare; -1 is the last; empty: every frame
};

struct Capture {
    bool enabled = true;
    double fps = 30;         // frames per simulated second
    double playbackFps = 0;  // frames per second of the video [1/s]; 0: fps (real time)
    int width = 1280, height = 720;
    int samples = 1;  // MSAA samples; 1: smoothed lines and silhouettes instead (much cheaper on llvmpipe)
    std::string colormap = "timestep";  // timestep | displacement | stress | none
    bool video = true;                  // MP4 through ffmpeg when it is installed
    int pngEvery = 1;                   // a PNG file for every n-th frame (0: none, the video has them all)
    bool hud = true;
    bool wireframe = false;
    bool xray = true;              // critical elements drawn through the surface
    double criticalFactor = 1.1;   // critical: element estimate < factor * dt
    double answeredSeconds = 0.5;  // how long frames show the critical elements a cut made and the step
                                   // policy answered [s]; 0: not shown
    double rangeMin = std::numeric_limits<double>::quiet_NaN();  // colour map range [map unit]; NaN: the map's
    double rangeMax = std::numeric_limits<double>::quiet_NaN();  // default (fixed for the whole run)
    bool floor = true;                                           // floor grid, for depth cues
    bool vtu = false;     // a .vtu per captured frame and a .pvd series (ParaView)
    bool cutObj = false;  // the surface with its cut faces as OBJ at the end
    double floorHeight = std::numeric_limits<double>::quiet_NaN();  // floor height along -gravity (z without
                                                                    // gravity) [m]; NaN: the rest shape's lowest point
    CheckSettings check;                                            // capture.check
};

// A scripted cut at a given time: the plane through point with normal, in world coordinates of
// the deformed object, optionally bounded by a polygon lying in that plane.
struct CutDef {
    double time = 0;                                    // [s]
    Eigen::Vector3d point = Eigen::Vector3d::Zero();    // [m]
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit
    std::vector<Eigen::Vector3d> polygon;               // corners [m], empty: the whole plane
    std::string path;                                   // key path, for messages
};

// How the object is cut (physics/cut/xfem.hpp).
struct Cutting {
    MassLumping lumping = MassLumping::Enrichment;  // cutting.lumping: row_sum | weighted_diagonal | enrichment
    double minFraction = CutOptions{}.minFraction;  // sides below this share of their element merge into the other [-]
    // cutting.exact_after_cut: the exact dt (global eigen-solve) after a cut. "stroke_end" (the
    // default): after each scripted cut, and for a blade once its stroke ends (its steps are backed
    // by the certified floor meanwhile); true: after each cut, every blade step included; false:
    // never (the certified floor backs every step).
    bool exactAfterCut = true;
    bool exactAtStrokeEnd = true;
    // Floor under the step after cuts, as a fraction of the uncut object's exact step (0: none;
    // explicit schemes only): local mass scaling (timestep/floor.hpp), certified by the exact
    // step when exactAfterCut, topped up globally when that is still under it.
    double stepFloor = 0.95;
    // cutting.floor_method "hybrid": before the mass, the elements whose R1R step is under the
    // floor are moved by shape matching (timestep/hybrid.hpp), so mass goes only where matching
    // them did not lift the step ("mass": mass alone).
    bool floorHybrid = false;
    bool mergeDebris = CutOptions{}.mergeDebris;         // CutOptions::mergeDebris
    int relaxIterations = CutOptions{}.relaxIterations;  // CutOptions::relaxIterations
    double lightShare = CutOptions{}.lightShare;         // CutOptions::lightShare [-]
    bool bladeSlot = true;                               // a blade slides in the area it swept (ContactWorld::setSlot)
    std::vector<std::string> compare;                    // baselines run on the rest mesh with the same planes:
                                                         // subdivision | remesh
    std::vector<CutDef> cuts;                            // in time order
};

CutOptions cutOptions(const Cutting& c);    // the engine's options as the scene sets them
CutSurface cutSurfaceOf(const CutDef& cd);  // the world-space surface of a scripted cut

struct SceneDef {
    std::string file;  // scene file path
    std::string dir;   // its folder: relative paths resolve against it
    std::string name;

    // object
    std::string mesh;                         // tet mesh path (resolved); empty when a box is generated
    std::shared_ptr<const TetMesh> meshData;  // object.mesh given inline ({nodes, tets}); null otherwise
    std::string surface;                      // surface path (resolved) embedded by mesh intersection; empty otherwise
    std::string tetraSurface;           // object.tetra.surface: surface path (resolved) meshed at load (sim/tetra.hpp)
    double tetraSize = 0;               // object.tetra.size: target edge length [m] (after scale)
    bool tetraImprove = true;           // object.tetra.improve
    Mesher tetraMesher = Mesher::Auto;  // object.tetra.mesher: auto, gmsh or tetgen
    int surfaceCells = 0;               // MI lattice cells across the surface's longest side (when surfaceH is 0)
    double surfaceH = 0;                // MI lattice cell edge [m] (after scale); > 0 takes precedence
    bool surfaceFixOutside = false;     // MI: fix the outside corners of interface tets (thesis sec. 6.3)
    bool surfaceKeepStep = true;        // MI: add mass where needed so the step is at least the lattice's
    std::string visual;      // object.visual: surface path (resolved) drawn on a tet mesh object; empty: none
    double visualScale = 1;  // its coordinates times this give meters (default: scale)
    Eigen::Vector3d boxSize = Eigen::Vector3d::Zero();    // generated box [0,size] (before scale) [m]
    Eigen::Vector3i boxCells = Eigen::Vector3i::Zero();   // cubes along each axis, 6 tets each
    double scale = 1;                                     // coordinates times scale give meters
    Eigen::Vector3d translate = Eigen::Vector3d::Zero();  // [m], after scale and rotation
    Eigen::Vector3d rotateDeg = Eigen::Vector3d::Zero();  // XYZ Euler angles [deg]
    bool reorient = false;                                // fix inverted tets instead of refusing the mesh
    bool reorder = true;            // object.reorder: a mesh file's nodes and elements in spatial order on load
    bool improve = false;           // object.improve: improve the tet mesh on load (improve/improve.hpp)
    ImproveOptions improveOptions;  // its options (material and fixed nodes set at load)
    bool anySize = false;           // object.any_size: allow an object under 1 mm or over 10 m across
    ElementModel element = ElementModel::Corotational;
    // object.element "hybrid": corotational FEM with the elements that would limit the step moved
    // by shape matching (timestep/hybrid.hpp), identified on load and after each cut.
    bool hybrid = false;
    double hybridThreshold = 1.1;  // object.hybrid_threshold: R1R step under this x dt_sim is matched [-]
    double matchStiffness = 1;     // object.match_stiffness: shape matching's alpha, (0, 1] [-]

    Material material;
    double damping = 0;  // mass-proportional damping [1/s]
    double toughness =
        0;  // material.toughness: fracture toughness G_c a blade pays per cut area [J/m^2]; 0: geometric cutting

    std::vector<Region> fixed;
    Eigen::Vector3d gravity = Eigen::Vector3d(0, 0, -9.81);  // [m/s^2]
    std::vector<ForceLoad> forces;

    Integrator integrator = Integrator::SymplecticEuler;
    double minStretch = 0;                                   // integrator.min_stretch: stretch limiting, 0 off [-]
    ImplicitSolver implicitSolver = ImplicitSolver::Direct;  // integrator.solver (backward Euler)
    ForcePrecision precision = ForcePrecision::Double;       // integrator.precision (explicit schemes)
    StepPolicy dt;                                           // integrator.dt
    double duration = 1;                                     // [s]
    double maxSteps = 1e8;  // integrator.max_steps: a run implying more steps is refused [-]
    Checks checks;

    Cutting cutting;
    std::vector<ToolDef> tools;          // rigid tools in contact with the object; empty: no Bullet world
    std::vector<ColliderDef> colliders;  // static shapes the object touches; with tools, the Bullet world
    ContactModel contactModel = ContactModel::Projection;  // contact.model
    bool pieceContact = false;   // contact.pieces: separated pieces of the object touch each other
    double pieceFriction = 0.3;  // contact.piece_friction: Coulomb coefficient between pieces [-]
    double contactSpacing = 0;   // largest gap between surface contact points [m]; 0 = automatic
    double forceRate = 1000;     // samples per second of the tool force series in report.json [1/s]

    std::vector<CameraKey> camera;  // empty: frame the object
    Capture capture;
    bool writeVtu = true;  // final.vtu

    nlohmann::json source;  // the scene as read, after --set overrides

    // The step options of this scene with scheme `integ` (its own, or a driver's) at step h;
    // alphaElem (per-element damping, may be empty) must outlive their use.
    StepOptions stepOptions(Integrator integ, double h, const Eigen::VectorXd& alphaElem) const {
        StepOptions so{integ, h};
        so.minStretch = minStretch;
        so.solver = implicitSolver;
        if (alphaElem.size()) so.alphaElem = &alphaElem;
        return so;
    }
};

// Why integrator.precision does not go with scheme `integ` (scene key and the viewer's switch),
// or null: single precision is for the explicit schemes (fem/model.hpp ForcePrecision).
const char* precisionConflict(Integrator integ, ForcePrecision precision);

// Reads and validates a scene file; `sets` are "key.path=value" overrides (value parsed as JSON,
// else taken as a string). Throws InputError naming the file and key path.
SceneDef loadScene(const std::string& path, const std::vector<std::string>& sets = {});
// The same overrides on a scene's JSON (array elements by index: tools.0.radius=0.02).
nlohmann::json applySets(nlohmann::json j, const std::vector<std::string>& sets);
SceneDef parseScene(const nlohmann::json& j, const std::string& file);

// Nodes of a mesh selected by a region (rest positions X).
std::vector<int> selectNodes(const Region& r, const Eigen::Matrix3Xd& X);

}  // namespace cutsim
