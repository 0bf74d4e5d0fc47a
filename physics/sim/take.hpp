// A take: a live run (cutsim view) written back as a scene, so `cutsim run` replays it offscreen.
// The scene with what the driver did applied (Simulation::takeLog): the tools' keys are the paths
// they took, the scripted cuts carry the times they were made, and the camera keys are the
// driver's, when it gives them.
#pragma once

#include "sim/simulation.hpp"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace cutsim {

// The scene of the take so far, to be written to outFile: the scene as read (after --set) with
// tools[i].keyframes, cutting.cuts[k].time and, when camera is given, camera.keyframes replaced,
// the duration cut to the time reached when the take ended early, and file paths made relative
// to outFile's folder.
nlohmann::json takeScene(const Simulation& sim, const std::string& outFile,
                         const std::vector<CameraKey>* camera = nullptr);

// Adds a frame's camera to a take's keys: nothing while it stands still, and when it moves after
// standing still, first the previous frame's camera, so the replay holds it until then.
void addCameraKey(std::vector<CameraKey>& keys, const CameraKey& previous, const CameraKey& now);

}  // namespace cutsim
