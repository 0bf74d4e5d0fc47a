// Projection contact (contact.model "projection", the default) with tools and static colliders:
// what lands on a floor stays on it and comes to rest, friction slows a slide as Coulomb says, and
// the demo's probe does not sink in.
#include "fem/forces.hpp"
#include "sim/simulation.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <utility>
#include <vector>

namespace cutsim {
namespace {

using nlohmann::json;

Simulation makeSim(const json& j, const std::string& name = "scene.json") {
    SimulationOptions o;
    o.threads = 1;
    return Simulation(parseScene(j, name), o);
}

// A free 2 cm cube of 48 tets, 1 cm above a floor at y = -0.01, falling under gravity.
json cubeOverFloor(double friction, const Eigen::Vector3d& gravity) {  // mass damping 50/s
    json j = json::parse(R"({
      "object": { "box": { "size": [0.02, 0.02, 0.02], "cells": [2, 2, 2] } },
      "material": { "E": 30000, "nu": 0.3, "rho": 1000, "damping": 50 },
      "colliders": [ { "kind": "plane", "point": [0, -0.01, 0], "normal": [0, 1, 0] } ],
      "duration": 0.4,
      "capture": { "enabled": false }
    })");
    j["colliders"][0]["friction"] = friction;
    j["loads"]["gravity"] = {gravity.x(), gravity.y(), gravity.z()};
    return j;
}

// Centre of mass (and its velocity, into v) of the nodes of the pieces that hold no fixed node;
// their kinetic energy relative to that velocity into internal [J], their fastest node's speed into
// fastest [m/s].
Eigen::Vector3d freeCentre(const Simulation& sim, Eigen::Vector3d* v = nullptr, double* internal = nullptr,
                           double* fastest = nullptr) {
    const Model& m = sim.model();
    std::vector<int> root(static_cast<size_t>(m.nodes()));
    std::iota(root.begin(), root.end(), 0);
    auto find = [&](int a) {
        while (root[static_cast<size_t>(a)] != a) a = root[static_cast<size_t>(a)];
        return a;
    };
    for (int e = 0; e < m.elements(); ++e)
        for (int k = 1; k < 4; ++k) root[static_cast<size_t>(find(m.tets(k, e)))] = find(m.tets(0, e));
    std::vector<char> held(static_cast<size_t>(m.nodes()), 0);
    for (int i = 0; i < m.nodes(); ++i) held[static_cast<size_t>(find(i))] |= m.fixed[static_cast<size_t>(i)];
    double mass = 0, kinetic = 0, top = 0;
    Eigen::Vector3d c = Eigen::Vector3d::Zero(), mv = Eigen::Vector3d::Zero();
    for (int i = 0; i < m.nodes(); ++i)
        if (!held[static_cast<size_t>(find(i))]) {
            mass += m.mass(i);
            c += m.mass(i) * sim.state().x.col(i);
            mv += m.mass(i) * sim.state().v.col(i);
            kinetic += 0.5 * m.mass(i) * sim.state().v.col(i).squaredNorm();
            top = std::max(top, sim.state().v.col(i).norm());
        }
    if (v) *v = mv / mass;
    if (internal) *internal = kinetic - 0.5 * mv.squaredNorm() / mass;
    if (fastest) *fastest = top;
    return c / mass;
}

double lowest(const Simulation& sim) { return sim.state().x.row(1).minCoeff() + 0.01; }  // above the floor

// Falling 1 cm takes 45 ms; the cube lands, stays on the floor (no point deeper than one step's
// fall allows), and by 0.4 s it is at rest with its weight on the floor.
TEST(Collider, CubeLandsOnTheFloorAndComesToRest) {
    Simulation sim = makeSim(cubeOverFloor(0.0, {0, -9.81, 0}));
    ASSERT_NE(sim.contact(), nullptr);  // a collider alone makes the Bullet world
    double deepest = 0;
    while (sim.step() == RunStatus::Running) deepest = std::min(deepest, lowest(sim));
    ASSERT_EQ(sim.status(), RunStatus::Finished) << sim.message();
    // never more than 0.1 mm below the floor after a step's projection
    EXPECT_GT(deepest, -1e-4);
    EXPECT_LT(lowest(sim), 1e-4);                                // landed
    EXPECT_LT(sim.state().v.colwise().norm().maxCoeff(), 1e-3);  // at rest [m/s]
}

// On a floor tilted by gravity's direction (tan = 0.5), with mass damping 50/s: frictionless, the
// cube slides at its terminal speed g sin / c = 8.8 cm/s; with mu = 0.2 it slides slower, and with
// mu = 0.8 (> tan) slower still. (Stiction is not exact: the soft, coarse cube rocks on its nodes
// and creeps; docs/method.md, Contact.)
TEST(Collider, CoulombFrictionSlowsASlide) {
    const double angle = std::atan(0.5);
    const Eigen::Vector3d g(9.81 * std::sin(angle), -9.81 * std::cos(angle), 0);
    auto slide = [&](double mu) {
        Simulation sim = makeSim(cubeOverFloor(mu, g));
        sim.advance(0.1);  // landed
        const double x0 = sim.state().x.row(0).mean();
        sim.advance(0.4);
        EXPECT_EQ(sim.status(), RunStatus::Finished) << sim.message();
        return sim.state().x.row(0).mean() - x0;
    };
    const double free = slide(0.0), some = slide(0.2), much = slide(0.8);
    EXPECT_NEAR(free, 0.3 * 9.81 * std::sin(angle) / 50, 0.004);  // terminal speed over 0.3 s
    EXPECT_LT(some, 0.8 * free);
    EXPECT_LT(much, 0.7 * some);
}

// The demo's 1 cm probe (MI liver, 2 cuts) stays out of the tissue: under 1 mm deep at any step.
TEST(Collider, DemoProbeDoesNotSinkIn) {
    SceneDef sc = loadScene(test::source("assets/scenes/demo.json"), {"duration=1.2", "cutting.cuts=[]"});
    Simulation sim(sc, SimulationOptions{1, false});
    sim.advance(1.2);
    ASSERT_EQ(sim.status(), RunStatus::Finished) << sim.message();
    EXPECT_GT(sim.record().tool.maxForce, 1.0);   // it pressed [N]
    EXPECT_LT(sim.record().tool.maxDepth, 1e-3);  // and did not sink in [m]
    EXPECT_LT(sim.contact()->last().residualDepth, 1e-5);
}

// A 2 x 2 x 4 cm column held at its base and cut through at mid-height (XFEM, at t = 0): its top
// half rests on its bottom half under gravity when pieces touch (contact.pieces, with no tool or
// collider in the scene), and falls through it when they do not. Measured on the free piece's
// centre of mass at the cut, at 0.2 s and at 0.4 s.
TEST(Collider, CutPiecesRestOnEachOther) {
    auto run = [](bool pieces) {
        json j = json::parse(R"({
          "object": { "box": { "size": [0.02, 0.02, 0.04], "cells": [2, 2, 4] } },
          "material": { "E": 30000, "nu": 0.3, "rho": 1000, "damping": 20 },
          "fixed": [ { "plane": { "point": [0, 0, 0], "normal": [0, 0, 1], "distance": 0.001 } } ],
          "loads": { "gravity": [0, 0, -9.81] },
          "cutting": { "cuts": [ { "time": 0.0, "point": [0, 0, 0.0205], "normal": [0, 0, 1] } ] },
          "duration": 0.4,
          "capture": { "enabled": false }
        })");
        j["contact"]["pieces"] = pieces;
        Simulation sim = makeSim(j);
        sim.step();  // the cut
        EXPECT_EQ(sim.record().cutsMade, 1);
        const Eigen::Vector3d start = freeCentre(sim);
        sim.advance(0.2);
        const Eigen::Vector3d settled = freeCentre(sim);
        while (sim.step() == RunStatus::Running) {}
        EXPECT_EQ(sim.status(), RunStatus::Finished) << sim.message();
        const Eigen::Vector3d end = freeCentre(sim);
        return std::make_pair(start.z() - end.z(), (end - settled).norm());
    };
    const auto [dropTouching, lastMove] = run(true);
    EXPECT_LT(dropTouching, 5e-4);      // it settles on the cut, squeezing it by less than half a millimetre [m]
    EXPECT_LT(lastMove, 2e-4);          // and stays there from 0.2 s to 0.4 s [m]
    EXPECT_GT(run(false).first, 0.05);  // without contact it falls through the bottom half
}

// The column of CutPiecesRestOnEachOther cut 2.9 degrees off level (tan = 0.051): with a piece
// friction of 0.3 the top half sticks on the slope (it moves under 0.05 mm from 0.2 s to 0.8 s,
// its settling done), with 0.03 it slides (Coulomb: a = g (sin - mu cos) = 0.2 m/s^2, near a
// terminal 10 mm/s under the 20/s mass damping). The friction impulse also undoes the step's
// tangential slide; without that the stuck half crept 5.6 mm in that time.
TEST(Collider, CutPiecesStickOnAGentleSlopeAndSlideWithLittleFriction) {
    auto slide = [](double mu) {
        const double a = 2.9 * std::acos(-1.0) / 180;
        json j = json::parse(R"({
          "object": { "box": { "size": [0.02, 0.02, 0.04], "cells": [2, 2, 4] } },
          "material": { "E": 30000, "nu": 0.3, "rho": 1000, "damping": 20 },
          "fixed": [ { "plane": { "point": [0, 0, 0], "normal": [0, 0, 1], "distance": 0.001 } } ],
          "loads": { "gravity": [0, 0, -9.81] },
          "contact": { "pieces": true },
          "duration": 0.8,
          "capture": { "enabled": false }
        })");
        j["cutting"]["cuts"] =
            json::array({{{"time", 0.0}, {"point", {0, 0, 0.0205}}, {"normal", {std::sin(a), 0, std::cos(a)}}}});
        j["contact"]["piece_friction"] = mu;
        Simulation sim = makeSim(j);
        sim.advance(0.2);
        const Eigen::Vector3d start = freeCentre(sim);
        sim.advance(0.8);
        EXPECT_EQ(sim.status(), RunStatus::Finished) << sim.message();
        return (freeCentre(sim) - start).x();
    };
    EXPECT_LT(std::abs(slide(0.3)), 5e-5);  // [m]
    EXPECT_GT(slide(0.03), 3e-3);
}

// blade.json severs the liver's front lobe by 0.47 s; it falls 3.5 cm onto the floor and comes to
// rest on it: from 1 s to 2.5 s its centre of mass stays 1.3-1.9 cm above the floor (about 1.7)
// and no surface point goes 1 mm into it; by 2.5 s its vibration has decayed as the scene's mass
// damping (5/s) lets it, from about 1 mJ at 1 s to under 1 uJ, and no node moves at 10 cm/s (one
// light node by the cut face, 0.16 g, keeps ringing at about 7 cm/s, 0.5 uJ).
// When the projection still corrected points through the cut's virtual nodes, the lobe kept about
// 3 mJ and nodes at 0.3-1 m/s to the end (docs/method.md, Contact).
TEST(Collider, BladesLobeLandsAndComesToRestOnTheFloor) {
    SceneDef sc = loadScene(test::source("assets/scenes/blade.json"));
    sc.duration = 2.5;
    Simulation sim(sc, SimulationOptions{1, false});
    sim.advance(1.0);
    ASSERT_EQ(sim.contact()->pieces(), 2);
    double deepest = 0, low = 1, high = -1;
    do {
        deepest = std::max(deepest, sim.contact()->last().colliderDepth);
        const double above = freeCentre(sim).y() + 0.03;  // the floor is at y = -0.03
        low = std::min(low, above), high = std::max(high, above);
    } while (sim.step() == RunStatus::Running);
    ASSERT_EQ(sim.status(), RunStatus::Finished) << sim.message();
    EXPECT_GT(low, 0.013);
    EXPECT_LT(high, 0.019);
    EXPECT_LT(deepest, 1e-3);
    double internal = 0, fastest = 0;
    freeCentre(sim, nullptr, &internal, &fastest);
    EXPECT_LT(internal, 1e-6);  // [J]
    EXPECT_LT(fastest, 0.1);    // [m/s]
}

// blade.json's stroke through the liver embedded in a 16-cell lattice (mesh intersection, about
// 5k tets), whose surface is finer than the shipped mesh: with cutting.blade_slot it runs to the
// end, the lobe severed, volume and mass kept by every cut and no element left inverted. Without
// the slot the blade's faces push the points each cut leaves within its thickness out sideways in
// one step and the run diverges 0.03 s into the stroke; without holding partial elements at
// stretch 0.5, a sliver of an interface element inverts and is thrown out after it (docs/method.md).
TEST(Blade, CutsTheLiverInASixteenCellLatticeToTheEnd) {
    SceneDef sc = loadScene(test::source("assets/scenes/blade.json"),
                            {"object={\"surface\": {\"path\": \"" + test::data("surface/sofa_liver.obj") +
                                 "\", \"cells\": 16}, \"scale\": 0.0254}",
                             "cutting.blade_slot=true"});
    Simulation sim(sc, SimulationOptions{1, false});
    ASSERT_GT(sim.model().elements(), 4000);
    sim.advance(sc.duration);
    ASSERT_EQ(sim.status(), RunStatus::Finished) << sim.message();
    EXPECT_GE(sim.contact()->pieces(), 2);
    EXPECT_GT(sim.record().bladeCutSteps, 20);
    for (const auto& c : sim.record().cuts) {
        EXPECT_LT(std::abs(c["volume_change"].get<double>()), 1e-9);
        EXPECT_LT(std::abs(c["mass_change"].get<double>()), 1e-9);
    }
    EXPECT_EQ(sim.state().flags.inverted, 0);
    // The severed lobe fell 3.5 cm (under 0.09 J for its 0.25 kg) and mass damping of 5/s takes
    // out all but e^-10 of its kinetic energy a second: it lies still. Contact and stretch
    // corrections with capped masses kept 0.3-0.45 J in the pieces to the end.
    EXPECT_LT(kineticEnergy(sim.model(), sim.state()), 0.03);
}

// blade.json's scene with its liver in a lattice of `cells` (MI), nothing fixed and no tool: the
// liver falls 3.5 cm onto the floor.
SceneDef droppedLatticeLiver(int cells, double duration) {
    return loadScene(test::source("assets/scenes/blade.json"),
                     {"object={\"surface\": {\"path\": \"" + test::data("surface/sofa_liver.obj") +
                          "\", \"cells\": " + std::to_string(cells) + "}, \"scale\": 0.0254}",
                      "fixed=[]", "tools=[]", "duration=" + std::to_string(duration)});
}

// blade.json's liver in a 16-cell lattice (MI), nothing fixed, no tool, dropped 3.5 cm onto the
// floor: no work is done on it but gravity's (in the total) and the floor's, so its total energy
// never rises above the start's, and mass damping brings it to rest. Projections with masses
// capped at their nodes' mean (not orthogonal in the mass norm) took it to 2.65 J from 0.49 J in
// 0.42 s (docs/method.md, "Cutting finer objects").
TEST(Collider, LatticeLiverDroppedOnTheFloorComesToRest) {
    const SceneDef sc = droppedLatticeLiver(16, 0.6);
    Simulation sim(sc, SimulationOptions{1, false});
    const double e0 = totalEnergy(sim.model(), sim.state());
    double most = e0;
    for (double t = 0.05; t <= sc.duration + 1e-9; t += 0.05) {
        ASSERT_NE(sim.advance(t), RunStatus::Diverged) << sim.message();
        most = std::max(most, totalEnergy(sim.model(), sim.state()));
    }
    EXPECT_LE(most, e0 * (1 + 1e-3));
    EXPECT_LT(kineticEnergy(sim.model(), sim.state()), 0.05 * e0);
    EXPECT_EQ(sim.state().flags.inverted, 0);
}

// The liver in a 24-cell lattice (~14k tets, cells of 7 mm under a surface whose edges are 2 cm)
// dropped onto the floor lands without inverting a cell, its contact points at most half a cell
// apart. The projection holding its surface points up moves the lighter lattice nodes below the
// surface past the heavier ones above them: with only light nodes' elements repaired after it, a
// cell stayed inverted from t = 0.10 s (and with the surface's vertices alone as contact points
// the run diverged at t = 0.13 s).
TEST(Collider, FinerLatticeLiverLandsWithoutInvertingItsCells) {
    const SceneDef sc = droppedLatticeLiver(24, 0.3);
    Simulation sim(sc, SimulationOptions{1, false});
    const double cell = (sim.model().X.col(sim.model().tets(1, 0)) - sim.model().X.col(sim.model().tets(0, 0)))
                            .cwiseAbs()
                            .maxCoeff();  // every lattice tet edge spans one cell along some axis
    EXPECT_LE(sim.contactSettings().spacing, 0.5 * cell * (1 + 1e-9));
    int landed = 0;
    RunStatus status = RunStatus::Running;
    while (status == RunStatus::Running && !HasFailure()) {
        status = sim.step();
        EXPECT_EQ(sim.state().flags.inverted, 0) << "t = " << sim.state().time;
        if (sim.contact()->last().colliderContacts > 0) ++landed;
    }
    EXPECT_EQ(status, RunStatus::Finished) << sim.message();
    EXPECT_GT(landed, 100);  // it did land
}

// cutting.exact_after_cut "stroke_end": a blade step is answered locally (no global solve); the
// step it takes is the policy's fraction of the certified bound, which the certified floor holds
// at min(step floor, uncut certified step); once the stroke ends the exact step is solved, the
// step returns to its fraction of it, and report "strokes" has the stroke's costs.
TEST(Blade, StrokeEndDefersTheExactStep) {
    SceneDef sc = loadScene(test::source("assets/scenes/blade.json"),
                            {"cutting.exact_after_cut=\"stroke_end\"", "cutting.blade_slot=true"});
    Simulation sim(sc, SimulationOptions{1, false});
    const StepLimits l0 = sim.initialLimits();
    const double aim = std::min(sc.cutting.stepFloor * l0.exact, l0.certified);
    sim.advance(sc.duration);
    sim.finish();
    ASSERT_EQ(sim.status(), RunStatus::Finished) << sim.message();
    const RunRecord& rec = sim.record();
    ASSERT_GT(rec.bladeCutSteps, 20);
    for (const auto& c : rec.cuts) {
        EXPECT_TRUE(c["exact_deferred"].get<bool>());
        EXPECT_TRUE(c["dt_after"]["exact"].is_null());
        const double cert = c["dt_after"]["certified"].get<double>();
        EXPECT_GE(cert, aim * (1 - 1e-9));
        EXPECT_LE(c["dt_used"].get<double>(), sc.dt.fraction * cert * (1 + 1e-12));
    }
    ASSERT_GE(rec.strokes.size(), 1u);
    long bladeSteps = 0;
    for (const auto& st : rec.strokes) {
        bladeSteps += st["blade_steps"].get<long>();
        const double exact = st["exact_after"].get<double>();
        EXPECT_GE(exact, sc.cutting.stepFloor * l0.exact * (1 - 1e-6));
        EXPECT_NEAR(st["dt_after"].get<double>(), sc.dt.fraction * exact, 1e-12 * exact);
        for (const char* k : {"cut", "timestep", "contact", "forces", "integrate"})
            EXPECT_GE(st["stages"][k].get<double>(), 0.0);
        EXPECT_GT(st["latency"]["p99"].get<double>(), 0.0);
    }
    EXPECT_EQ(bladeSteps, rec.bladeCutSteps);
    // the exact step the stroke's end solved is the model's, from scratch
    EXPECT_NEAR(sim.limits().exact, exactCriticalDt(sim.model()).dt, 1e-6 * sim.limits().exact);
    EXPECT_NEAR(sim.dt(), sc.dt.fraction * sim.limits().exact, 1e-12 * sim.dt());
}

// A collider needs a known kind and its keys; errors name them.
TEST(Collider, BadCollidersNameTheKey) {
    json j = cubeOverFloor(0.5, {0, -9.81, 0});
    j["colliders"][0]["kind"] = "cone";
    EXPECT_THROW(
        {
            try {
                parseScene(j, "c.json");
            } catch (const InputError& e) {
                EXPECT_NE(std::string(e.what()).find("colliders[0].kind"), std::string::npos) << e.what();
                throw;
            }
        },
        InputError);
    j["colliders"][0] = json::parse(R"({ "kind": "box", "size": [0.1, -1, 0.1] })");
    EXPECT_THROW(parseScene(j, "c.json"), InputError);
    j["colliders"][0] = json::parse(R"({ "kind": "plane", "point": [0, 0, 0] })");
    EXPECT_THROW(parseScene(j, "c.json"), InputError);
    // contact between pieces exists in the projection model only: asked with penalty, refused
    j = cubeOverFloor(0.5, {0, -9.81, 0});
    j["contact"] = json::parse(R"({ "model": "penalty", "pieces": true })");
    try {
        parseScene(j, "c.json");
        ADD_FAILURE() << "penalty with pieces was accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("contact.pieces"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace cutsim
