// What a frame of a scene shows, built from the simulation's state: the surface with its colour map,
// the critical elements, the camera and the HUD values. Shared by captured frames, the live view
// and the Python bindings; no GL here (render/ draws the RenderSnapshot).
#pragma once

#include "fem/state.hpp"
#include "mesh/embedding.hpp"
#include "sim/scene.hpp"
#include "snapshot/snapshot.hpp"

#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace cutsim {

struct FrameInfo {
    double time = 0;         // simulated time [s]
    double dt = 0;           // step used [s]
    double dtCertified = 0;  // certified limit [s]
    double dtExact = 0;      // exact limit [s] (NaN when unknown)
    int criticalElements = 0;
    int cuts = 0;
    double wall = 0;                                      // wall time since the loop started [s]; NaN: the
                                                          // HUD shows no wall-clock rates
    std::vector<ToolShape> tools;                         // tools to draw
    Eigen::Vector3d toolForce = Eigen::Vector3d::Zero();  // reaction force on the tools [N]
    std::vector<float> forceHistory;                      // recent |tool force| samples, oldest first [N]
    const char* cutPhase = nullptr;  // material.toughness: the blade's phase (idle | pressing | cutting); null: off
    std::vector<int> answered;       // elements a recent cut made critical and the step policy answered
};

// What a frame of a scene shows (surface, colour map, critical elements, HUD values), built from
// the state; shared by captured frames and the live view. The surface is extracted once; later
// frames move its vertices.
class SceneSnapshot {
public:
    // surface, when given, is drawn instead of the mesh's boundary (an embedded object's fine surface).
    SceneSnapshot(const SceneDef& sc, const Model& model, const Eigen::VectorXd& elementDt, double dt,
                  const EmbeddedSurface* surface = nullptr);
    RenderSnapshot& update(const Model& model, const State& state, const FrameInfo& info);

    // Changes that rebuild the surface on the next update.
    void setStep(double dt, double criticalFactor);  // colours and critical elements follow dt
    // After a cut: the new mesh, the surface to draw, and the new per-element limits (nElems) [s].
    void topologyChanged(const Model& model, EmbeddedSurface surface, const Eigen::VectorXd& elementDt, double dt);
    void setColormap(const std::string& name);  // timestep | displacement | stress | none
    void setWireframe(bool on);
    const std::string& colormap() const { return colormap_; }
    bool wireframe() const { return wireframe_; }
    Camera defaultCamera(const Model& model, double time);  // the scene's camera at time, or framing the object
    std::pair<double, double> mapRange() const;             // the colour map's fixed range [map unit]
    const Floor& floor() const { return floor_; }           // where the scene puts the floor

private:
    const SceneDef& sc_;
    TetMesh mesh_;
    Eigen::VectorXd elementDt_;  // per-element stable step estimates (nElems) [s]
    double dt_;
    std::string colormap_;
    bool wireframe_;
    Eigen::Vector3d up_;
    std::vector<int> critical_;
    std::unique_ptr<EmbeddedSurface> surface_;  // null: the mesh's boundary faces
    std::unique_ptr<MeshSnapshot> ms_;
    std::unique_ptr<Camera> camera_;
    Floor floor_;
    double restDiagonal_ = 1;  // rest shape's bounding-box diagonal [m]
    double youngs_ = 1;        // Young's modulus [Pa]
};

class Simulation;
// The HUD values and tool shapes of the simulation's state now; wall: seconds since its loop began.
FrameInfo frameInfoOf(const Simulation& sim, double wall);

}  // namespace cutsim
