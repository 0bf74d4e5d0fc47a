// Capture pipeline of a run: physics fills a snapshot, the renderer draws it, frames go to PNG
// files and a video. Only created when a scene captures and rendering is on.
#pragma once

#include "fem/state.hpp"
#include "mesh/embedding.hpp"
#include "scene.hpp"

#include <memory>
#include <string>

namespace cutsim::app {

struct FrameInfo {
    double time = 0;          // simulated time [s]
    double dt = 0;            // step used [s]
    double dtCertified = 0;   // certified limit [s]
    double dtExact = 0;       // exact limit [s] (NaN when unknown)
    int criticalElements = 0;
    int cuts = 0;
    double wall = 0;          // wall time since the loop started [s]
};

class FrameSink {
public:
    virtual ~FrameSink() = default;
    virtual void frame(const Model& model, const State& state, const FrameInfo& info) = 0;
    virtual void finish() = 0;                    // flush PNGs, close the video
    virtual int frames() const = 0;
    virtual std::string videoPath() const = 0;    // "" when no video was made
    virtual double lastEncodeSeconds() const = 0; // part of the last frame() spent handing off/encoding
};

// A sink for the scene's capture settings, or nullptr with a message on stderr when this build
// has no renderer or no GL context can be made (the run goes on without frames). surface, when
// given, is drawn instead of the mesh's boundary (an embedded object's fine surface; not owned).
std::unique_ptr<FrameSink> makeFrameSink(const SceneDef& scene, const std::string& outDir, const Model& model,
                                         const Eigen::VectorXd& elementDt, double dt,
                                         const EmbeddedSurface* surface = nullptr);

} // namespace cutsim::app
