// What a run records as it goes: the loop appends, Simulation::report() writes it (report.json,
// docs/scene-format.md "report.json").
#pragma once

#include "util/stopwatch.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace cutsim {

// The stages of a run whose wall time the report gives; the first six are Simulation::step()'s,
// in the order it runs them.
enum class Stage : std::uint8_t { Loads, Contact, Cuts, Forces, Integrate, Checks, Timestep, Render, Encode, Count };
inline constexpr int kStages = static_cast<int>(Stage::Count);
const char* stageName(Stage s);  // report keys: loads contact cut forces integrate checks timestep render encode

// Wall time per stage, as mjData's timers: an array indexed by the enum. Time is charged by
// StageTimer scopes to the innermost stage open, so a stage opened inside another (the exact step
// after a cut, inside the cut stage) pauses the outer one and nothing is timed by subtraction.
struct StageTimes {
    std::array<double, kStages> seconds{};  // [s]
    Stage current = Stage::Count;           // the stage open now (Count: none)
    WallClock::time_point since{};          // when time was last charged to it
    double& operator[](Stage s) { return seconds[static_cast<size_t>(s)]; }
    double operator[](Stage s) const { return seconds[static_cast<size_t>(s)]; }
    // Charges the time since the last switch to the open stage and opens s; returns the stage
    // that was open.
    Stage open(Stage s) {
        const auto now = WallClock::now();
        if (current != Stage::Count) (*this)[current] += std::chrono::duration<double>(now - since).count();
        since = now;
        return std::exchange(current, s);
    }
    // Moves `s` seconds of stage `from`'s time to stage `to`: the part a callee timed itself as
    // another stage (the Stepper's force time inside its step).
    void reassign(Stage from, Stage to, double s) {
        (*this)[from] -= s;
        (*this)[to] += s;
    }
    nlohmann::json toJson() const;
};

// Times its scope as stage s; the stage open before resumes at its end.
class StageTimer {
public:
    StageTimer(StageTimes& t, Stage s) : t_(t), outer_(t.open(s)) {}
    ~StageTimer() { t_.open(outer_); }
    StageTimer(const StageTimer&) = delete;
    StageTimer& operator=(const StageTimer&) = delete;

private:
    StageTimes& t_;
    Stage outer_;
};

// Warnings a run raises, as mjData's: an array indexed by the enum, each with how often it was
// raised and what it said the first time. The library raises them; the program prints them and
// report.json lists them ("warnings").
enum class Warning : std::uint8_t {
    KeepStepMass,          // object.surface.keep_step added over a percent of the mass, or missed the step
    ToolStiffnessClamped,  // a tool's stiffness was above the stable limit and lowered to it
    TetraNotCached,        // object.tetra built the mesh but could not write it to the cache
    Count
};
inline constexpr int kWarnings = static_cast<int>(Warning::Count);
const char* warningName(Warning w);  // keep_step_mass | tool_stiffness_clamped | tetra_not_cached

struct WarningStat {
    int count = 0;
    std::string first;  // what it said the first time
};

struct Warnings {
    std::array<WarningStat, kWarnings> stat{};
    void raise(Warning w, std::string text) {
        WarningStat& s = stat[static_cast<size_t>(w)];
        if (s.count++ == 0) s.first = std::move(text);
    }
    const WarningStat& operator[](Warning w) const { return stat[static_cast<size_t>(w)]; }
    nlohmann::json toJson() const;  // [{kind, count, message}] of those raised
};

// Contact set-up of a scene (Simulation's, from its tools).
struct ContactSettings {
    double spacing = 0;                // largest gap between contact points [m]
    double stiffnessLimit = 0;         // stable penalty stiffness per point [N/m]; inf for backward Euler
    double massRef = 1;                // effective mass of a point with the full penalty [kg]
    std::vector<std::string> clamped;  // tools whose stiffness was lowered to the limit
};

// The tool force record: the full-rate maximum and a series sampled every sampleDt.
struct ToolRecord {
    double maxForce = 0;                                // largest |reaction| at full rate [N]
    double maxDepth = 0;                                // deepest surface point inside a tool at any step [m]
    long contactSteps = 0;                              // steps with at least one point in contact
    Eigen::Vector3d force = Eigen::Vector3d::Zero();    // reaction of the last step [N]
    std::vector<double> time, fx, fy, fz, blockMaxima;  // the series: mean force over each sample's window [s], [N]
    std::vector<float> history;                         // |F| at the series rate, last 200 samples (HUD plot) [N]
    double nextSample = 0, blockMax = 0, sampleDt = 1e-3;
    Eigen::Vector3d impulse = Eigen::Vector3d::Zero();  // sum of f dt since the last sample [N s]
    double window = 0;                                  // its duration [s]
    // After a step [t, t + dt] with reaction `f`, deepest point `depth`, `contacts` points touching.
    // A sample is the mean force since the previous one (impulse over time, as a force sensor
    // reads it): the projection contact's reaction comes in impulses, one step at a time.
    void add(double t, double dt, const Eigen::Vector3d& f, double depth, int contacts);
};

struct RunRecord {
    StageTimes stages;
    Warnings warnings;
    nlohmann::json cuts = nlohmann::json::array();     // one entry per topology change
    nlohmann::json strokes = nlohmann::json::array();  // one entry per blade stroke: its costs by stage
    nlohmann::json energy = nlohmann::json::array();   // samples {time, kinetic, elastic, gravity, total} [s], [J]
    long invertedSteps = 0, limitedSteps = 0;          // steps with inverted / stretch-limited elements
    int maxInverted = 0, maxLimited = 0;
    long solverIterations = 0;  // backward Euler CG iterations, summed
    int solverIterationsMax = 0;
    double maxSpeed = 0;         // largest node speed seen [m/s]
    double maxDisplacement = 0;  // largest node displacement seen [m]
    int cutsMade = 0;            // cuts that split elements (a blade stroke counts once)
    long bladeCutSteps = 0;      // steps in which a blade split elements
    double floorMass = 0;        // mass the step floor added after cuts (cutting.step_floor) [kg]
    ToolRecord tool;
    nlohmann::json compare;  // cutting.compare results (null: none)
    nlohmann::json initial;  // the object before the first step: nodes, elements, fixed_nodes, mass
    double wallSetup = 0;    // seconds to build and analyse the object [s]
    double wallLoop = 0;     // seconds in step() [s]
};

}  // namespace cutsim
