// What drivers do to a run as it runs (a held tool, a scripted cut made sooner), kept as events:
// the take (sim/take.hpp) is the scene with them applied, and the scene itself stays as read.
#pragma once

#include "contact/tool.hpp"
#include "sim/scene.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstddef>
#include <optional>
#include <vector>

namespace cutsim {

struct TakeLog {
    struct Hold {  // Simulation::holdTool
        int tool;
        double time;  // [s]
        Eigen::Vector3d position;
        std::optional<Eigen::Quaterniond> orientation;
    };
    struct Cut {  // scripted cut `index` made, or made due, at `time`, sooner than the scene has it
        size_t index;
        double time;  // [s]
    };
    std::vector<Hold> holds;  // in the order they came
    std::vector<Cut> cuts;
    // When scripted cut k of sc is made: the last time a driver gave it, else the scene's.
    double cutTime(const SceneDef& sc, size_t k) const {
        for (auto c = cuts.rbegin(); c != cuts.rend(); ++c)
            if (c->index == k) return c->time;
        return sc.cutting.cuts[k].time;
    }
};

// A hold on a tool's keys: the pose at `now` stays what the step ending then saw, the held pose
// starts one tick of time later, and the keys from now on are dropped, so the keys are the path the
// tool took. Without an orientation the tool keeps the one it has now.
void holdToolKeys(ToolDef& t, double now, const Eigen::Vector3d& position,
                  const std::optional<Eigen::Quaterniond>& orientation);

}  // namespace cutsim
