// Capture pipeline of a run: physics fills a snapshot, the renderer draws it, frames go to PNG
// files and a video. Only created when a scene captures and rendering is on.
#pragma once

#include "snapshot/scene_snapshot.hpp"

#include <nlohmann/json.hpp>

#include <memory>
#include <string>

namespace cutsim::app {

class FrameSink {
public:
    virtual ~FrameSink() = default;
    virtual void frame(const Model& model, const State& state, const FrameInfo& info) = 0;
    virtual void finish() = 0;  // flush PNGs, close the video
    virtual int frames() const = 0;
    virtual std::string videoPath() const = 0;     // "" when no video was made
    virtual double lastEncodeSeconds() const = 0;  // part of the last frame() spent handing off/encoding
    // The renderer that drew the frames: GL_VENDOR, GL_RENDERER, GL_VERSION.
    virtual nlohmann::json renderer() const = 0;
    // After a cut: the surface to draw from now on, and the new per-element limits (nElems) [s].
    virtual void topologyChanged(const Model& model, EmbeddedSurface surface, const Eigen::VectorXd& elementDt,
                                 double dt) = 0;
};

// A sink for the scene's capture settings, or nullptr with a message on stderr when this build
// has no renderer or no GL context can be made (the run goes on without frames). surface, when
// given, is drawn instead of the mesh's boundary (an embedded object's fine surface; not owned).
std::unique_ptr<FrameSink> makeFrameSink(const SceneDef& scene, const std::string& outDir, const Model& model,
                                         const Eigen::VectorXd& elementDt, double dt,
                                         const EmbeddedSurface* surface = nullptr);

}  // namespace cutsim::app
