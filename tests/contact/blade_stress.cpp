// Random blade strokes through Simulation (the stress label): blade.json's liver, material, fixing
// and floor, with the blade drawn at random (where it crosses the object, its plane, the tilt of
// its path in that plane, its speed) on the shipped liver (596 tets), the liver in 16- and 32-cell
// lattices (MI, ~5k and ~33k tets) and the liver meshed by object.tetra (~16k tets). Every stroke must end
// ok with nothing inverted, conserve volume and mass through each cut, and never step above its
// limit: the exact one where it is known, else the certified one.
#include "sim/simulation.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

namespace cutsim {
namespace {

using json = nlohmann::json;

struct Stroke {
    Eigen::Vector3d through, normal, edge;  // a point of the path, the blade's plane, its edge
    double tilt = 0;                        // path direction off the edge's normal, in the plane [rad]
    double speed = 0;                       // [m/s]
};

Stroke randomStroke(std::mt19937& rng, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
    std::uniform_real_distribution<double> uni(0, 1);
    Stroke s;
    for (int k = 0; k < 3; ++k) s.through[k] = lo[k] + (0.25 + 0.5 * uni(rng)) * (hi[k] - lo[k]);
    // planes within 60 degrees of blade.json's (z), edges anywhere in them
    const double polar = std::acos(1 - uni(rng) * 0.5), azim = 2 * M_PI * uni(rng);
    s.normal = Eigen::Vector3d(std::sin(polar) * std::cos(azim), std::sin(polar) * std::sin(azim), std::cos(polar));
    Eigen::Vector3d a = s.normal.unitOrthogonal(), b = s.normal.cross(a);
    const double turn = 2 * M_PI * uni(rng);
    s.edge = std::cos(turn) * a + std::sin(turn) * b;
    s.tilt = (uni(rng) - 0.5) * (M_PI / 3);  // up to 30 degrees either way
    s.speed = 0.2 + 0.6 * uni(rng);
    return s;
}

std::string describe(const Stroke& s) {
    char buf[300];
    std::snprintf(buf, sizeof buf,
                  "through (%.4f %.4f %.4f) normal (%.3f %.3f %.3f) edge (%.3f %.3f %.3f) tilt %.3f speed %.3f",
                  s.through.x(), s.through.y(), s.through.z(), s.normal.x(), s.normal.y(), s.normal.z(), s.edge.x(),
                  s.edge.y(), s.edge.z(), s.tilt, s.speed);
    return buf;
}

// The blade (0.2 x 0.03 x 0.001 m) and its two keys: from outside the object's box to past it.
json bladeTool(const Stroke& s, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double* travelTime) {
    const Eigen::Vector3d height = s.normal.cross(s.edge);  // local y: the edge is at -y / 2
    const Eigen::Vector3d path = -(std::cos(s.tilt) * height) + std::sin(s.tilt) * s.edge;
    const double reach = 0.5 * (hi - lo).norm() + 0.03;
    Eigen::Matrix3d R;
    R.col(0) = s.edge, R.col(1) = height, R.col(2) = s.normal;
    const Eigen::Quaterniond q(R);
    const Eigen::Vector3d centre = 0.5 * (lo + hi);
    // the path crosses `through`; start and end where the blade is clear of the box
    const Eigen::Vector3d mid = s.through + path * path.dot(centre - s.through);
    const Eigen::Vector3d from = mid - reach * path, to = mid + reach * path;
    *travelTime = 2 * reach / s.speed;
    auto key = [&](double t, const Eigen::Vector3d& p) {
        return json{{"time", t}, {"position", {p.x(), p.y(), p.z()}}, {"quaternion", {q.w(), q.x(), q.y(), q.z()}}};
    };
    return json{{"name", "scalpel"},
                {"kind", "blade"},
                {"size", {0.2, 0.03, 0.001}},
                {"keyframes", {key(0, from), key(*travelTime, to)}}};
}

void runStrokes(const std::string& object, int strokes, unsigned seed, const std::vector<std::string>& sets = {}) {
    const std::string base = test::source("assets/scenes/blade.json");
    std::mt19937 rng(seed);
    // the object's rest box, from a run of the scene that takes no step
    SceneDef probe = loadScene(base, {"object=" + object, "tools=[]", "colliders=[]"});
    const Simulation shape(probe, SimulationOptions{1, false});
    const Eigen::Vector3d lo = shape.model().X.rowwise().minCoeff(), hi = shape.model().X.rowwise().maxCoeff();
    int withCuts = 0;
    for (int k = 0; k < strokes; ++k) {
        const Stroke s = randomStroke(rng, lo, hi);
        double travel = 0;
        const json tool = bladeTool(s, lo, hi, &travel);
        std::vector<std::string> all = {"object=" + object, "tools=[" + tool.dump() + "]",
                                        "duration=" + std::to_string(travel + 0.05)};
        all.insert(all.end(), sets.begin(), sets.end());
        SceneDef sc = loadScene(base, all);
        Simulation sim(sc, SimulationOptions{1, false});
        sim.advance(sc.duration);
        sim.finish();
        const std::string what = "stroke " + std::to_string(k) + ": " + describe(s);
        ASSERT_EQ(sim.status(), RunStatus::Finished) << what << ": " << sim.message();
        EXPECT_EQ(sim.state().flags.inverted, 0) << what;
        const RunRecord& rec = sim.record();
        withCuts += rec.bladeCutSteps > 0;
        for (const json& c : rec.cuts) {
            EXPECT_LT(std::abs(c["volume_change"].get<double>()), 1e-9) << what;
            EXPECT_LT(std::abs(c["mass_change"].get<double>()), 1e-9) << what;
            const json& after = c["dt_after"];
            const double limit =
                after["exact"].is_null() ? after["certified"].get<double>() : after["exact"].get<double>();
            EXPECT_LE(c["dt_used"].get<double>(), sc.dt.fraction * limit * (1 + 1e-12)) << what;
        }
        for (const json& st : rec.strokes) {
            EXPECT_LE(st["dt_after"].get<double>(), sc.dt.fraction * st["exact_after"].get<double>() * (1 + 1e-12))
                << what;
        }
        if (rec.bladeCutSteps > 0) {  // the exact step the end settled is the cut model's, from scratch
            EXPECT_NEAR(sim.limits().exact, exactCriticalDt(sim.model()).dt, 1e-6 * sim.limits().exact) << what;
        }
    }
    EXPECT_GE(withCuts, strokes / 2);  // the strokes do cross the object
}

const std::string kLiver = R"({"mesh": "../meshes/liver.msh", "scale": 0.0254})";

TEST(BladeStress, RandomStrokesThroughTheShippedLiver) { runStrokes(kLiver, 140, 1); }

// material.toughness on: the blade presses the liver before it cuts (cut/toughness.hpp)
TEST(BladeStress, RandomStrokesThroughTheShippedLiverWithLiverToughness) {
    runStrokes(kLiver, 40, 4, {"material.toughness=200"});
}

TEST(BladeStress, RandomStrokesThroughTheLiverInASixteenCellLattice) {
    runStrokes(R"({"surface": {"path": "../meshes/sofa_liver.obj", "cells": 16}, "scale": 0.0254})", 40, 2);
}

TEST(BladeStress, RandomStrokesThroughTheLiverInAThirtyTwoCellLattice) {
    runStrokes(R"({"surface": {"path": "../meshes/sofa_liver.obj", "cells": 32}, "scale": 0.0254})", 12, 5);
}

TEST(BladeStress, RandomStrokesThroughATetraLiver) {
    runStrokes(
        R"({"tetra": {"surface": "../meshes/sofa_liver.obj", "size": 0.0075, "mesher": "tetgen"}, "scale": 0.0254})",
        20, 3);
}

}  // namespace
}  // namespace cutsim
