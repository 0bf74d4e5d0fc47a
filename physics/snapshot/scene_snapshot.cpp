#include "snapshot/scene_snapshot.hpp"

#include <cmath>

#include "fem/forces.hpp"
#include "sim/simulation.hpp"

#include <algorithm>
#include <cstdio>

namespace cutsim {

namespace {
// Camera at time t: linear interpolation between keyframes, held before the first and after the last.
Camera cameraAt(const std::vector<CameraKey>& keys, double t) {
    Camera c;
    const CameraKey* a = &keys.front();
    const CameraKey* b = a;
    for (size_t i = 0; i < keys.size(); ++i) {
        if (keys[i].time <= t) a = &keys[i];
        if (keys[i].time >= t) {
            b = &keys[i];
            break;
        }
        b = &keys[i];
    }
    const double w = b->time > a->time ? std::clamp((t - a->time) / (b->time - a->time), 0.0, 1.0) : 0.0;
    c.eye = (1 - w) * a->eye + w * b->eye;
    c.target = (1 - w) * a->target + w * b->target;
    c.up = ((1 - w) * a->up + w * b->up).normalized();
    c.fovY = (1 - w) * a->fov + w * b->fov;
    return c;
}
}  // namespace

SceneSnapshot::SceneSnapshot(const SceneDef& sc, const Model& model, const Eigen::VectorXd& elementDt, double dt,
                             const EmbeddedSurface* surface)
    : sc_(sc), elementDt_(elementDt), dt_(dt), colormap_(sc.capture.colormap), wireframe_(sc.capture.wireframe) {
    if (surface) surface_ = std::make_unique<EmbeddedSurface>(*surface);
    mesh_.X = model.X;
    mesh_.tets = model.tets;
    up_ = model.gravity.norm() > 0 ? Eigen::Vector3d(-model.gravity.normalized()) : Eigen::Vector3d::UnitZ();
    setStep(dt, sc.capture.criticalFactor);
}

void SceneSnapshot::setStep(double dt, double criticalFactor) {
    dt_ = dt;
    critical_.clear();
    for (int e = 0; e < static_cast<int>(elementDt_.size()); ++e)
        if (elementDt_(e) < criticalFactor * dt_) critical_.push_back(e);
    ms_.reset();
}

void SceneSnapshot::topologyChanged(const Model& model, EmbeddedSurface surface, const Eigen::VectorXd& elementDt,
                                    double dt) {
    mesh_.X = model.X;
    mesh_.tets = model.tets;
    elementDt_ = elementDt;
    surface_ = std::make_unique<EmbeddedSurface>(std::move(surface));
    setStep(dt, sc_.capture.criticalFactor);  // also drops the snapshot: rebuilt from the new surface
}

void SceneSnapshot::setColormap(const std::string& name) {
    colormap_ = name;
    ms_.reset();
}

void SceneSnapshot::setWireframe(bool on) {
    wireframe_ = on;
    ms_.reset();
}

Camera SceneSnapshot::defaultCamera(const Model& model, double time) {
    if (!sc_.camera.empty()) return cameraAt(sc_.camera, time);
    if (!camera_) {
        const Eigen::Vector3d lo = model.X.rowwise().minCoeff(), hi = model.X.rowwise().maxCoeff();
        camera_ = std::make_unique<Camera>(frameBox(lo, hi, up_));
    }
    return *camera_;
}

RenderSnapshot& SceneSnapshot::update(const Model& model, const State& state, const FrameInfo& info) {
    MeshSnapshotOptions so;
    so.wireframe = wireframe_;
    so.critical = critical_;
    Eigen::VectorXd values;
    const std::string& cmap = colormap_;
    if (cmap == "timestep") {
        values = elementDt_ / dt_;  // element's estimated stable step over the step used
        so.elementValues = &values;
        so.name = "element dt / dt";
        so.unit = std::string(1, '-');  // not = "-": GCC 12 -Wrestrict false positive
    } else if (cmap == "stress") {
        values = vonMisesStress(model, state);
        so.elementValues = &values;
        so.name = "von Mises stress";
        so.unit = "Pa";
    }
    // The surface is extracted once; later frames move its vertices and refresh changing fields.
    if (!ms_) {
        ms_ = std::make_unique<MeshSnapshot>(surface_ ? snapshotFromSurface(mesh_, state.x, *surface_, so)
                                                      : snapshotFromTetMesh(mesh_, state.x, so));
    } else {
        updateSnapshotPositions(*ms_, mesh_, state.x, so);
        if (cmap == "stress") setElementValues(*ms_, mesh_, so);
    }
    MeshSnapshot& ms = *ms_;
    RenderSnapshot& snap = ms.snap;
    if (cmap == "timestep") {
        // 1 = as fast as the step itself; critical elements sit below criticalFactor
        snap.scalarMin = 1;
        snap.scalarMax = 2.5;
    } else if (cmap == "displacement") {
        Eigen::Matrix3Xd rest;
        embeddedPositions(ms.surface, mesh_.tets, model.X, rest);
        snap.scalar = (snap.positions - rest).colwise().norm().transpose();
        snap.scalarName = "displacement";
        snap.scalarUnit = "m";
        snap.scalarMin = 0;
        snap.scalarMax = std::max(1e-9, snap.scalar.size() ? snap.scalar.maxCoeff() : 0.0);
    }
    snap.camera = defaultCamera(model, info.time);
    HudValues& h = snap.hud;
    h = HudValues{};
    h.simTime = info.time;
    h.dtUsed = info.dt;
    h.dtCertified = info.dtCertified;
    h.dtExact = info.dtExact;
    h.stepsPerSecond = std::isnan(info.wall) ? info.wall : info.wall > 0 ? state.steps / info.wall : 0;
    h.realTimeFactor = std::isnan(info.wall) ? info.wall : info.wall > 0 ? info.time / info.wall : 0;
    h.criticalElements = info.criticalElements;
    h.cuts = info.cuts;
    h.lines.push_back(sc_.name + ": " + std::to_string(model.elements()) + " tets, " + std::to_string(model.nodes()) +
                      " nodes");
    snap.tools = info.tools;
    if (!sc_.tools.empty()) {
        char line[96];
        std::snprintf(line, sizeof line, "tool F   %.3f N (%.3f, %.3f, %.3f)", info.toolForce.norm(),
                      info.toolForce.x(), info.toolForce.y(), info.toolForce.z());
        h.lines.push_back(line);
        h.forcePlot = info.forceHistory;
    }
    return snap;
}

FrameInfo frameInfoOf(const Simulation& sim, double wall) {
    FrameInfo fi;
    fi.time = sim.state().time;
    fi.dt = sim.dt();
    fi.dtCertified = sim.limits().certified;
    fi.dtExact = sim.limits().exact;
    fi.criticalElements = sim.criticalElements();
    fi.cuts = sim.record().cutsMade;
    fi.wall = wall;
    fi.toolForce = sim.record().tool.force;
    fi.forceHistory = sim.record().tool.history;
    if (sim.contact())
        for (const auto& t : sim.contact()->tools()) appendToolShapes(t, fi.time, fi.tools);
    return fi;
}

}  // namespace cutsim
