#include "frames.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>

#ifdef CUTSIM_HAVE_RENDER
#include "png_writer.hpp"
#include "renderer.hpp"
#include "video.hpp"
#endif

namespace cutsim::app {

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
        ro.floor = sc.capture.floor;
        ro.hud = sc.capture.hud;
        ro.samples = sc.capture.samples;
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
                                                                sc.capture.playbackFps > 0 ? sc.capture.playbackFps
                                                                                           : sc.capture.fps);
            }
        }
    }

    void frame(const Model& model, const State& state, const FrameInfo& info) override {
        renderer_->draw(scene_.update(model, state, info));
        const bool png = sc_.capture.pngEvery > 0 && frames_ % sc_.capture.pngEvery == 0;
        render::Image img = video_ && !png ? video_->spareFrame() : render::Image{};
        renderer_->read(img);
        const auto t0 = Clock::now();
        char name[32];
        std::snprintf(name, sizeof name, "frame_%06d.png", frames_);
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
