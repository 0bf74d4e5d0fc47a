// Capture pipeline of a run: physics fills a snapshot, the renderer draws it, frames go to PNG
// files and a video. Only created when a scene captures and rendering is on.
#pragma once

#include "snapshot/scene_snapshot.hpp"

#include <nlohmann/json.hpp>

#include <memory>
#include <string>

namespace cutsim::app {

// Where a run's capture time went [s]: on the caller's thread the snapshot of each frame's state
// (and its copy) and the waits for the drawing thread; on that thread drawing, reading back and
// handing the frame to the PNG and video writers; at the end the writers' drain (finish).
struct CaptureTimes {
    int frames = 0;  // frames drawn
    bool pipelined = true;
    double snapshot = 0, draw = 0, read = 0, handoff = 0, finish = 0, waited = 0;
    double render() const { return snapshot + draw + read; }  // report.json stage "render"
    double encode() const { return handoff + finish; }        // and "encode"
    nlohmann::json toJson() const;
};

class FrameSink {
public:
    virtual ~FrameSink() = default;
    // The object to draw, once the simulation is built; throws std::runtime_error when no GL
    // context could be made (the run goes on without frames). surface, when given, is drawn
    // instead of the mesh's boundary (an embedded object's fine surface; not owned).
    virtual void begin(const Model& model, const Eigen::VectorXd& elementDt, double dt,
                       const EmbeddedSurface* surface) = 0;
    // Takes a frame of the state now; drawn later on the sink's own thread (pipelined) or before
    // this returns. Rethrows an error of an earlier frame.
    virtual void frame(const Model& model, const State& state, const FrameInfo& info) = 0;
    virtual void finish() = 0;  // waits for the frames, flushes PNGs, closes the video
    virtual int frames() const = 0;
    virtual std::string videoPath() const = 0;  // "" when no video was made
    virtual CaptureTimes times() const = 0;     // so far
    // The renderer that drew the frames: GL_VENDOR, GL_RENDERER, GL_VERSION.
    virtual nlohmann::json renderer() const = 0;
    // After a cut: the surface to draw from now on, and the new per-element limits (nElems) [s].
    virtual void topologyChanged(const Model& model, EmbeddedSurface surface, const Eigen::VectorXd& elementDt,
                                 double dt) = 0;
};

// A sink for the scene's capture settings writing into outDir (frames/, video.mp4), its drawing
// thread and the video encoder started (making the GL context, compiling shaders and starting
// ffmpeg while the simulation is built); nullptr with a message on stderr when this build has no
// renderer. pipelined: frames are drawn while the caller steps on; false: each frame() waits for
// its frame.
std::unique_ptr<FrameSink> makeFrameSink(const SceneDef& scene, const std::string& outDir, bool pipelined = true);

}  // namespace cutsim::app
