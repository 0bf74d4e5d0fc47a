#include "frames.hpp"

#include "util/stopwatch.hpp"

#include <cstdio>
#include <filesystem>

#ifdef CUTSIM_HAVE_RENDER
#include "png_writer.hpp"
#include "renderer.hpp"
#include "video.hpp"

#include <array>
#include <condition_variable>
#include <deque>
#include <exception>
#include <future>
#include <mutex>
#include <thread>
#include <vector>
#endif

namespace cutsim::app {

nlohmann::json CaptureTimes::toJson() const {
    return {{"frames", frames},         {"pipelined", pipelined},  {"snapshot_seconds", snapshot},
            {"draw_seconds", draw},     {"read_seconds", read},    {"handoff_seconds", handoff},
            {"finish_seconds", finish}, {"waited_seconds", waited}};
}

#ifdef CUTSIM_HAVE_RENDER
namespace {

// The frames are drawn, read back and handed to the PNG and video writers on a thread of their
// own (the GL context is current there), while the caller's thread goes on stepping: a frame's
// snapshot is copied at its time, so what is drawn is that frame's state whatever the threads do.
// One frame waits while one is drawn; a third waits for the drawer (`waited`).
class RenderSink final : public FrameSink {
public:
    // Starts the drawing thread, which makes the GL context and the renderer meanwhile, then starts
    // the video encoder.
    RenderSink(const SceneDef& sc, const std::string& outDir, bool pipelined) : sc_(sc), pipelined_(pipelined) {
        times_.pipelined = pipelined;
        render::RenderOptions ro;
        ro.width = sc.capture.width;
        ro.height = sc.capture.height;
        ro.wireframe = sc.capture.wireframe;
        ro.xray = sc.capture.xray;
        ro.floor = sc.capture.floor;
        ro.hud = sc.capture.hud;
        ro.samples = sc.capture.samples;
        outDir_ = outDir;
        dir_ = std::filesystem::path(outDir) / "frames";
        made_ = ready_.get_future();
        drawer_ = std::thread([this, ro] { drawLoop(ro); });
    }

    void begin(const Model& model, const Eigen::VectorXd& elementDt, double dt,
               const EmbeddedSurface* surface) override {
        made_.get();  // the renderer's constructor threw there when no GL context could be made
        if (videoError_) std::rethrow_exception(videoError_);
        std::filesystem::create_directories(dir_);
        scene_ = std::make_unique<SceneSnapshot>(sc_, model, elementDt, dt, surface);
    }

    ~RenderSink() override { stopDrawer(); }

    void frame(const Model& model, const State& state, const FrameInfo& info) override {
        const Stopwatch t;
        const RenderSnapshot& snap = scene_->update(model, state, info);
        RenderSnapshot copy;
        double waited = 0;
        {
            std::unique_lock lock(mutex_);
            const Stopwatch w;
            changed_.wait(lock, [&] { return queue_.empty() || error_; });
            waited = w.seconds();
            times_.waited += waited;
            rethrow();
            if (!spare_.empty()) {
                copy = std::move(spare_.back());
                spare_.pop_back();
            }
        }
        copy = snap;  // the buffers of a drawn frame reused
        std::unique_lock lock(mutex_);
        queue_.push_back({std::move(copy), frames_++});
        times_.snapshot += t.seconds() - waited;
        changed_.notify_all();
        if (!pipelined_) {
            const Stopwatch w;
            changed_.wait(lock, [&] { return (queue_.empty() && !busy_) || error_; });
            times_.waited += w.seconds();
            rethrow();
        }
    }

    void topologyChanged(const Model& model, EmbeddedSurface surface, const Eigen::VectorXd& elementDt,
                         double dt) override {
        scene_->topologyChanged(model, std::move(surface), elementDt, dt);
    }

    void finish() override {
        const Stopwatch t;
        {
            std::unique_lock lock(mutex_);
            changed_.wait(lock, [&] { return (queue_.empty() && !busy_) || error_; });
            rethrow();
        }
        pngs_.flush();
        if (video_) video_->finish();
        std::lock_guard lock(mutex_);
        times_.finish += t.seconds();
    }
    int frames() const override { return frames_; }
    std::string videoPath() const override { return video_ ? videoPath_ : ""; }
    CaptureTimes times() const override {
        std::lock_guard lock(mutex_);
        return times_;
    }
    nlohmann::json renderer() const override {
        return {{"vendor", info_[0]}, {"renderer", info_[1]}, {"version", info_[2]}};
    }

private:
    struct Job {
        RenderSnapshot snap;
        int index = 0;
    };

    void startVideo(const std::string& outDir) {
        if (!sc_.capture.video) return;
        if (render::findOnPath("ffmpeg").empty()) {
            std::fprintf(stderr, "frames: ffmpeg is not installed (apt-get install ffmpeg); writing PNG frames only\n");
        } else if (sc_.capture.width % 2 || sc_.capture.height % 2) {
            std::fprintf(stderr, "frames: video needs an even width and height; writing PNG frames only\n");
        } else {
            videoPath_ = (std::filesystem::path(outDir) / "video.mp4").string();
            video_ = std::make_unique<render::VideoEncoder>(videoPath_, sc_.capture.width, sc_.capture.height,
                                                            sc_.capture.playbackFps > 0 ? sc_.capture.playbackFps
                                                                                        : sc_.capture.fps);
        }
    }

    void drawLoop(const render::RenderOptions& ro) {
        std::unique_ptr<render::Renderer> renderer;
        try {
            renderer = std::make_unique<render::Renderer>(ro);
            info_ = {renderer->glVendor(), renderer->glRenderer(), renderer->glVersion()};
            renderer->warmUp();  // shaders compiled while the simulation is built, not in its frames
        } catch (...) {
            ready_.set_exception(std::current_exception());
            return;
        }
        // ffmpeg starts now: loading its libraries overlaps the rest of the simulation's set-up
        // (on the core the warm-up had), not the first frames
        try {
            startVideo(outDir_);
        } catch (...) {
            videoError_ = std::current_exception();  // begin throws it
        }
        ready_.set_value();
        // the frame buffers the first frames would otherwise allocate, made while the simulation is built
        if (sc_.capture.pngEvery > 0) pngs_.reserve(kPngSpares, ro.width, ro.height);
        if (video_) video_->reserve();
        std::unique_lock lock(mutex_);
        for (;;) {
            if (queue_.empty() && busy_) {  // nothing to draw: the frame read last goes out now
                lock.unlock();
                double handoff = 0;
                std::exception_ptr err;
                try {
                    handOffRead(handoff);
                } catch (...) {
                    err = std::current_exception();
                }
                lock.lock();
                busy_ = false;
                if (err && !error_) error_ = err;
                times_.handoff += handoff;
                changed_.notify_all();
                continue;
            }
            changed_.wait(lock, [&] { return stop_ || !queue_.empty(); });
            if (queue_.empty()) return;  // stopped and nothing left
            Job job = std::move(queue_.front());
            queue_.pop_front();
            if (error_) continue;  // drain: the caller rethrows
            busy_ = true;
            lock.unlock();
            double draw = 0, read = 0, handoff = 0;
            std::exception_ptr err;
            try {
                drawOne(*renderer, job, draw, read, handoff);
            } catch (...) {
                err = std::current_exception();
            }
            lock.lock();
            if (err && !error_) error_ = err;
            times_.draw += draw;
            times_.read += read;
            times_.handoff += handoff;
            ++times_.frames;
            spare_.push_back(std::move(job.snap));
            changed_.notify_all();
        }
    }

    // Draws a frame and reads it back; the frame read before it is handed to the PNG and video
    // writers while llvmpipe rasterises this one (draw flushes), and this one waits in read_ for
    // the next frame or for the queue to run dry. busy_ stays set while a frame waits there.
    void drawOne(render::Renderer& renderer, const Job& job, double& draw, double& read, double& handoff) {
        Stopwatch t;
        renderer.draw(job.snap);
        draw = t.lap();
        handOffRead(handoff);
        t.lap();
        readIndex_ = job.index;
        const bool png = sc_.capture.pngEvery > 0 && job.index % sc_.capture.pngEvery == 0;
        read_ = png ? pngs_.spare() : std::move(frame_);
        renderer.read(read_);
        read = t.lap();
    }

    // Hands the frame in read_ (if any) to the PNG and video writers.
    void handOffRead(double& handoff) {
        if (readIndex_ < 0) return;
        const Stopwatch t;
        if (video_) video_->addFrame(read_);
        const bool png = sc_.capture.pngEvery > 0 && readIndex_ % sc_.capture.pngEvery == 0;
        if (png) {
            char name[32];
            std::snprintf(name, sizeof name, "frame_%06d.png", readIndex_);
            pngs_.push((dir_ / name).string(), std::move(read_));
        } else {
            frame_ = std::move(read_);
        }
        readIndex_ = -1;
        handoff += t.seconds();
    }

    void stopDrawer() {
        if (!drawer_.joinable()) return;
        {
            std::lock_guard lock(mutex_);
            stop_ = true;
        }
        changed_.notify_all();
        drawer_.join();
    }

    void rethrow() {  // with the lock held
        if (error_) std::rethrow_exception(error_);
    }

    const SceneDef& sc_;
    bool pipelined_;
    std::filesystem::path dir_;
    std::unique_ptr<SceneSnapshot> scene_;  // the caller's thread only
    std::promise<void> ready_;              // the renderer is made (or failed)
    std::future<void> made_;
    static constexpr std::size_t kPngSpares = 4;  // frames in flight to the PNG writers in real runs
    render::PngWriter pngs_{8};                   // one encoder thread per core
    std::unique_ptr<render::VideoEncoder> video_;
    std::exception_ptr videoError_;  // from starting the video
    std::string outDir_;
    render::Image frame_;  // the read-back of frames without a PNG, its buffer reused
    render::Image read_;   // the frame read last, not yet handed off (drawing thread only)
    int readIndex_ = -1;   // its index; -1: none
    std::string videoPath_;
    std::array<std::string, 3> info_;  // GL_VENDOR, GL_RENDERER, GL_VERSION
    int frames_ = 0;

    mutable std::mutex mutex_;  // guards what follows
    std::condition_variable changed_;
    std::deque<Job> queue_;
    std::vector<RenderSnapshot> spare_;
    bool busy_ = false, stop_ = false;
    std::exception_ptr error_;
    CaptureTimes times_;
    std::thread drawer_;
};

}  // namespace
#endif

std::unique_ptr<FrameSink> makeFrameSink(const SceneDef& scene, const std::string& outDir, bool pipelined) {
#ifdef CUTSIM_HAVE_RENDER
    return std::make_unique<RenderSink>(scene, outDir, pipelined);
#else
    (void)scene, (void)outDir, (void)pipelined;
    std::fprintf(stderr, "frames: this build has no renderer; running without frames\n");
    return nullptr;
#endif
}

}  // namespace cutsim::app
