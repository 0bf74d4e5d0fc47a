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
    // The floor, once from the rest shape: it must not follow falling pieces.
    floor_.fixed = sc.capture.floor;
    floor_.normal = up_;
    const Eigen::Vector3d lo = model.X.rowwise().minCoeff(), hi = model.X.rowwise().maxCoeff();
    floor_.height =
        std::isnan(sc.capture.floorHeight) ? (up_.transpose() * model.X).minCoeff() : sc.capture.floorHeight;
    // a floor collider (the first plane) is the floor drawn, unless capture.floor_height says otherwise
    for (const ColliderDef& c : sc.colliders)
        if (c.kind == ColliderDef::Kind::Plane && std::isnan(sc.capture.floorHeight)) {
            floor_.normal = c.normal();
            floor_.height = floor_.normal.dot(c.pose.position);
            break;
        }
    floor_.centre = 0.5 * (lo + hi);
    const double radius = std::max(0.5 * (hi - lo).norm(), 1e-6);
    floor_.spacing = niceGridStep(radius / 4);
    floor_.halfSize = std::ceil(2.0 * radius / floor_.spacing) * floor_.spacing;
    // Colour map ranges, fixed for the run so noise and falling pieces do not rescale the map.
    restDiagonal_ = 2 * radius;
    youngs_ = sc.material.E;
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

std::pair<double, double> SceneSnapshot::mapRange() const {
    if (!std::isnan(sc_.capture.rangeMin)) return {sc_.capture.rangeMin, sc_.capture.rangeMax};
    // The smallest of 1, 2, 5 times a power of ten at or above x: legend ticks that read well.
    auto niceAbove = [](double x) {
        const double p = std::pow(10.0, std::floor(std::log10(x)));
        for (double m : {1.0, 2.0, 5.0})
            if (m * p >= x * (1 - 1e-12)) return m * p;
        return 10 * p;
    };
    if (colormap_ == "timestep") return {1, 2.5};  // 1: as fast as the step itself; critical below criticalFactor
    if (colormap_ == "displacement") return {0, niceAbove(0.05 * restDiagonal_)};  // 5 % of the object's size
    return {0, niceAbove(0.05 * youngs_)};                                         // stress: that of 5 % strain
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
    if (cmap == "displacement") {
        Eigen::Matrix3Xd rest;
        embeddedPositions(ms.surface, mesh_.tets, model.X, rest);
        snap.scalar = (snap.positions - rest).colwise().norm().transpose();
        snap.scalarName = "displacement";
        snap.scalarUnit = "m";
    }
    if (cmap != "none") {
        const auto [lo, hi] = mapRange();
        snap.scalarMin = lo;
        snap.scalarMax = hi;
    }
    snap.camera = defaultCamera(model, info.time);
    snap.floor = floor_;
    HudValues& h = snap.hud;
    h = HudValues{};
    h.simTime = info.time;
    h.dtUsed = info.dt;
    h.dtCertified = info.dtCertified;
    h.dtExact = info.dtExact;
    h.stepsPerSecond = std::isnan(info.wall) ? info.wall : info.wall > 0 ? state.steps / info.wall : 0;
    h.realTimeFactor = std::isnan(info.wall) ? info.wall : info.wall > 0 ? info.time / info.wall : 0;
    h.criticalElements = info.criticalElements;
    for (int e : critical_)
        if (e < elementDt_.size())
            h.criticalStep = std::isnan(h.criticalStep) ? elementDt_(e) : std::min(h.criticalStep, elementDt_(e));
    h.cuts = info.cuts;
    h.lines.push_back(sc_.name + ": " + std::to_string(model.elements()) + " tets, " + std::to_string(model.nodes()) +
                      " nodes");
    // The elements a recent cut made critical and the policy answered, corners at this state.
    snap.answeredTets.resize(3, 4 * static_cast<Eigen::Index>(info.answered.size()));
    int k = 0;
    for (int e : info.answered)
        if (e >= 0 && e < model.elements())
            for (int a = 0; a < 4; ++a) snap.answeredTets.col(k++) = state.x.col(model.tets(a, e));
    snap.answeredTets.conservativeResize(3, k);
    h.answeredElements = k / 4;
    snap.tools = info.tools;
    if (!sc_.tools.empty()) {
        char line[96];
        std::snprintf(line, sizeof line, "tool F   %.3f N (%.3f, %.3f, %.3f)", info.toolForce.norm(),
                      info.toolForce.x(), info.toolForce.y(), info.toolForce.z());
        h.lines.push_back(line);
        if (info.cutPhase) {  // the edge presses the tissue until it pays G_c per area (cut/toughness.hpp)
            std::snprintf(line, sizeof line, "blade    %s (G_c %g J/m^2)", info.cutPhase, sc_.toughness);
            h.lines.push_back(line);
        }
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
    // over a frame's interval: in steady cutting the front alternates pressing and cutting steps
    if (sim.scene().toughness > 0) fi.cutPhase = cutPhaseName(sim.cutPhaseOver(1 / sim.scene().capture.fps));
    for (const Simulation::Answered& a : sim.answered())
        if (a.time >= fi.time - sim.scene().capture.answeredSeconds) fi.answered.push_back(a.element);
    if (sim.contact())
        for (const auto& t : sim.contact()->tools()) appendToolShapes(t, fi.time, fi.tools);
    return fi;
}

}  // namespace cutsim
