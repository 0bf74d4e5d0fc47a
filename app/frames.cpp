#include "frames.hpp"

#include "fem/forces.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

#ifdef CUTSIM_HAVE_RENDER
#include "png_writer.hpp"
#include "renderer.hpp"
#include "video.hpp"
#endif

namespace cutsim::app {

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
    return snap;
}

#ifdef CUTSIM_HAVE_RENDER
namespace {

using Clock = std::chrono::steady_clock;

class RenderSink final : public FrameSink {
public:
    RenderSink(const SceneDef& sc, const std::string& outDir, const Model& model, const Eigen::VectorXd& elementDt,
               double dt, const EmbeddedSurface* surface)
        : sc_(sc), dir_(std::filesystem::path(outDir) / "frames"), scene_(sc, model, elementDt, dt, surface) {
        render::RenderOptions ro;
        ro.width = sc.capture.width;
        ro.height = sc.capture.height;
        ro.wireframe = sc.capture.wireframe;
        ro.xray = sc.capture.xray;
        ro.hud = sc.capture.hud;
        renderer_ = std::make_unique<render::Renderer>(ro);
        std::filesystem::create_directories(dir_);
        if (sc.capture.video) {
            if (render::findOnPath("ffmpeg").empty()) {
                std::fprintf(stderr,
                             "frames: ffmpeg is not installed (apt-get install ffmpeg); writing PNG frames only\n");
            } else if (sc.capture.width % 2 || sc.capture.height % 2) {
                std::fprintf(stderr, "frames: video needs an even width and height; writing PNG frames only\n");
            } else {
                videoPath_ = (std::filesystem::path(outDir) / "video.mp4").string();
                video_ = std::make_unique<render::VideoEncoder>(videoPath_, sc.capture.width, sc.capture.height,
                                                                sc.capture.fps);
            }
        }
    }

    void frame(const Model& model, const State& state, const FrameInfo& info) override {
        RenderSnapshot& snap = scene_.update(model, state, info);
        snap.tools = info.tools;
        if (!sc_.tools.empty()) {
            HudValues& h = snap.hud;
            char line[96];
            std::snprintf(line, sizeof line, "tool F   %.3f N (%.3f, %.3f, %.3f)", info.toolForce.norm(),
                          info.toolForce.x(), info.toolForce.y(), info.toolForce.z());
            h.lines.push_back(line);
            h.forcePlot = info.forceHistory;
        }
        render::Image img = renderer_->render(snap);
        const auto t0 = Clock::now();
        char name[32];
        std::snprintf(name, sizeof name, "frame_%06d.png", frames_);
        const bool png = sc_.capture.pngEvery > 0 && frames_ % sc_.capture.pngEvery == 0;
        if (video_ && png)
            video_->addFrame(img);
        else if (video_)
            video_->addFrame(std::move(img));
        if (png) pngs_.push((dir_ / name).string(), std::move(img));
        ++frames_;
        encode_ = std::chrono::duration<double>(Clock::now() - t0).count();
    }

    void topologyChanged(const Model& model, EmbeddedSurface surface, const Eigen::VectorXd& elementDt,
                         double dt) override {
        scene_.topologyChanged(model, std::move(surface), elementDt, dt);
    }

    void finish() override {
        pngs_.flush();
        if (video_) video_->finish();
    }
    int frames() const override { return frames_; }
    std::string videoPath() const override { return video_ ? videoPath_ : ""; }
    double lastEncodeSeconds() const override { return encode_; }
    nlohmann::json renderer() const override {
        return {{"vendor", renderer_->glVendor()},
                {"renderer", renderer_->glRenderer()},
                {"version", renderer_->glVersion()}};
    }

private:
    const SceneDef& sc_;
    std::filesystem::path dir_;
    SceneSnapshot scene_;
    std::unique_ptr<render::Renderer> renderer_;
    render::PngWriter pngs_{8};  // one encoder thread per core
    std::unique_ptr<render::VideoEncoder> video_;
    std::string videoPath_;
    int frames_ = 0;
    double encode_ = 0;
};

}  // namespace
#endif

std::unique_ptr<FrameSink> makeFrameSink(const SceneDef& scene, const std::string& outDir, const Model& model,
                                         const Eigen::VectorXd& elementDt, double dt, const EmbeddedSurface* surface) {
#ifdef CUTSIM_HAVE_RENDER
    try {
        return std::make_unique<RenderSink>(scene, outDir, model, elementDt, dt, surface);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "frames: no rendering (%s); running without frames\n", e.what());
        return nullptr;
    }
#else
    (void)scene, (void)outDir, (void)model, (void)elementDt, (void)dt, (void)surface;
    std::fprintf(stderr, "frames: this build has no renderer; running without frames\n");
    return nullptr;
#endif
}

}  // namespace cutsim::app
