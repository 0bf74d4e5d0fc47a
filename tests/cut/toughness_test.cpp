// material.toughness (cut/toughness.hpp): a slab of width b clamped at its base, cut straight down
// by a blade wider than it, slowly and without friction. Griffith for a rigid edge on the crack
// tip: the steady force is G_c b, whatever the mesh, and proportional to G_c; the blade's work
// goes into elastic, kinetic and fracture energy.
#include "sim/simulation.hpp"
#include "snapshot/scene_snapshot.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace cutsim {
namespace {

using json = nlohmann::json;

constexpr double kSlabWidth = 0.02;  // b [m]: the slab is 2 x 2 x 2 cm, the blade 6 cm wide

// The blade's edge enters the top at 0.067 s and moves down 16 mm at 3 cm/s; the base is clamped.
// E = 100 kPa: G_c b is a small load for the ligament under the edge, whose relaxation as the cut
// shortens it then feeds little of the crack, so the energy balance asks a force close to G_c b
// (at 50 kPa and G_c = 100 J/m^2 it asks more than the account may raise the cap, and the edge
// crushes the slab's top).
json toughSlab(double gc, int cells, double damping) {
    return json{{"name", "tough-slab"},
                {"object", {{"box", {{"size", {kSlabWidth, 0.02, 0.02}}, {"cells", {cells, cells, cells + 1}}}}}},
                {"material", {{"E", 1e5}, {"nu", 0.3}, {"rho", 1000}, {"damping", damping}, {"toughness", gc}}},
                {"fixed", {{{"plane", {{"point", {0, 0, 0}}, {"normal", {0, 1, 0}}, {"distance", 1e-4}}}}}},
                {"loads", {{"gravity", {0, 0, 0}}}},
                {"tools",
                 {{{"name", "blade"},
                   {"kind", "blade"},
                   {"size", {0.06, 0.03, 0.001}},
                   {"keyframes",
                    {{{"time", 0.0}, {"position", {0.01, 0.037, 0.0101}}},
                     {{"time", 0.6}, {"position", {0.01, 0.019, 0.0101}}}}}}}},
                {"duration", 0.6}};
}

struct ToughRun {
    json report;
    double steady = 0;  // mean force along the cutting direction over 0.30-0.55 s [N]
};

// Without mass damping: the ledger counts its share on velocities the projection then stops.
ToughRun runToughSlab(double gc, int cells) {
    const SceneDef sc = parseScene(toughSlab(gc, cells, 0), "tough-slab.json");
    Simulation sim(sc, SimulationOptions{1, false});
    sim.advance(sc.duration);
    sim.finish();
    EXPECT_EQ(sim.status(), RunStatus::Finished) << sim.message();
    ToughRun r;
    r.report = sim.report();
    const json& s = r.report["blade"]["toughness"]["series"];
    double sum = 0;
    int n = 0;
    for (size_t i = 0; i < s["time"].size(); ++i) {
        const double t = s["time"][i].get<double>();
        if (t >= 0.30 && t <= 0.55) sum += s["force"][i].get<double>(), ++n;
    }
    r.steady = n > 0 ? sum / n : 0.0;
    return r;
}

TEST(Toughness, SteadyForceIsToughnessTimesWidthOnTwoMeshes) {
    const double gc = 100, expected = gc * kSlabWidth;  // 2 N
    const ToughRun coarse = runToughSlab(gc, 4), fine = runToughSlab(gc, 8);
    EXPECT_NEAR(coarse.steady, expected, 0.15 * expected);
    EXPECT_NEAR(fine.steady, expected, 0.15 * expected);
    EXPECT_NEAR(coarse.steady, fine.steady, 0.15 * fine.steady);
    // the phases: the edge presses first, then cuts; the fracture energy is G_c times the area
    for (const ToughRun* r : {&coarse, &fine}) {
        const json& t = r->report["blade"]["toughness"];
        const json& ph = t["phases"];
        ASSERT_GE(ph.size(), 3u);
        EXPECT_EQ(ph[0]["phase"], "idle");
        EXPECT_EQ(ph[1]["phase"], "pressing");
        EXPECT_EQ(ph[2]["phase"], "cutting");
        EXPECT_GT(t["cutting_steps"].get<long>(), 0);
        EXPECT_DOUBLE_EQ(t["energy"]["fracture"].get<double>(), gc * t["cut_area"].get<double>());
        // the crack runs 12-16 mm into the 2 cm wide slab (the blade travels 16 mm past the top)
        EXPECT_GT(t["cut_area"].get<double>(), 0.012 * kSlabWidth);
        EXPECT_LT(t["cut_area"].get<double>(), 0.016 * kSlabWidth * 1.05);
        EXPECT_GT(r->report["blade"]["cut_steps"].get<long>(), 0);
    }
}

TEST(Toughness, SteadyForceIsProportionalToToughness) {
    const ToughRun half = runToughSlab(50, 4), full = runToughSlab(100, 4);
    EXPECT_NEAR(half.steady, 50 * kSlabWidth, 0.15 * 50 * kSlabWidth);
    EXPECT_NEAR(half.steady / full.steady, 0.5, 0.15 * 0.5);
}

// The work goes to elastic, kinetic and fracture energy: the front's account makes the blade pay
// also for the crack the relaxing ligament carries past its edge (docs/method.md, "Tissue
// toughness"), which a cap of G_c b alone cuts unpaid.
TEST(Toughness, EnergyBalanceOfTheCut) {
    for (int cells : {4, 8})
        for (double gc : {50.0, 100.0}) {
            const ToughRun r = runToughSlab(gc, cells);
            const json& e = r.report["blade"]["toughness"]["energy"];
            const double work = e["work"].get<double>();
            EXPECT_GT(work, gc * kSlabWidth * 0.012);  // a 12 mm crack's worth at least
            const double sum = e["elastic"].get<double>() + e["kinetic"].get<double>() + e["fracture"].get<double>() +
                               e["damping"].get<double>();
            EXPECT_NEAR(sum, work, 0.05 * work) << "cells " << cells << ", G_c " << gc << ": " << e.dump();
            EXPECT_NEAR(e["residual"].get<double>(), work - sum, 1e-12);
        }
}

// The HUD says what the edge does: pressing until the front pays, then cutting, over a frame's
// interval (in steady cutting the front alternates pressing and cutting steps).
TEST(Toughness, TheHudShowsTheBladesPhase) {
    const SceneDef sc = parseScene(toughSlab(100, 4, 20), "tough-slab.json");
    Simulation sim(sc, SimulationOptions{1, false});
    SceneSnapshot snap(sc, sim.model(), Eigen::VectorXd::Constant(sim.model().elements(), 1.0), sim.dt());
    auto hud = [&] {
        const auto& lines =
            snap.update(sim.model(), sim.state(), frameInfoOf(sim, std::numeric_limits<double>::quiet_NaN())).hud.lines;
        for (const std::string& l : lines)
            if (l.rfind("blade    ", 0) == 0) return l;
        return std::string();
    };
    EXPECT_EQ(hud(), "blade    idle (G_c 100 J/m^2)");
    int pressing = 0, cutting = 0;
    double lastCut = -1;
    while (sim.state().time < 0.4 && sim.step() == RunStatus::Running) {
        if (sim.cutPhase() == CutPhase::Cutting) lastCut = sim.state().time;
        const bool cutRecently = lastCut >= 0 && sim.state().time - lastCut < 1 / sc.capture.fps - 1e-9;
        if (sim.cutPhase() == CutPhase::Pressing && lastCut < 0) {
            EXPECT_EQ(hud(), "blade    pressing (G_c 100 J/m^2)") << sim.state().time;
            ++pressing;
        } else if (cutRecently) {
            EXPECT_EQ(hud(), "blade    cutting (G_c 100 J/m^2)") << sim.state().time;
            ++cutting;
        }
    }
    EXPECT_GT(pressing, 0);
    EXPECT_GT(cutting, 0);
    // without toughness the HUD has no phase line
    const SceneDef plain = parseScene(toughSlab(0, 4, 20), "tough-slab.json");
    const Simulation geometric(plain, SimulationOptions{1, false});
    EXPECT_EQ(frameInfoOf(geometric, 0).cutPhase, nullptr);
}

// A toughness the edge's force cannot reach (G_c b = 2 kN): the edge presses until the tissue
// under it is crushed to half its volume, then cuts there, and no whole element under the edge is
// ever inverted (the cut pieces beside the blade are the contact's).
TEST(Toughness, AnEdgeCutsWhereItCrushesTheTissue) {
    const SceneDef sc = parseScene(toughSlab(1e5, 4, 20), "tough-slab.json");
    Simulation sim(sc, SimulationOptions{1, false});
    double least = 1;  // smallest volume ratio of a whole element over the run
    while (sim.step() == RunStatus::Running) {
        const Model& m = sim.model();
        for (int e = 0; e < m.elements(); ++e) {
            if (m.fraction(e) < 1) continue;
            Eigen::Matrix3d d;
            for (int c = 0; c < 3; ++c)
                d.col(c) = sim.state().x.col(m.tets(c + 1, e)) - sim.state().x.col(m.tets(0, e));
            least = std::min(least, (d * m.dmInv(e)).determinant());
        }
    }
    ASSERT_EQ(sim.status(), RunStatus::Finished) << sim.message();
    const json t = sim.report()["blade"]["toughness"];
    EXPECT_GT(t["cutting_steps"].get<long>(), 0);
    EXPECT_EQ(t["crushed_steps"].get<long>(), t["cutting_steps"].get<long>());  // every one crushed
    EXPECT_LT(t["peak_force"].get<double>(), 0.1 * 1e5 * kSlabWidth);
    EXPECT_GT(t["cut_area"].get<double>(), 0.01 * kSlabWidth);  // the crack runs on, 10 mm and more
    EXPECT_GT(least, 0.0);
    // the ordinary toughness is paid by the force on this mesh: no step is crushed
    EXPECT_EQ(runToughSlab(100, 4).report["blade"]["toughness"]["crushed_steps"].get<long>(), 0);
}

TEST(Toughness, ZeroToughnessCutsGeometrically) {
    const SceneDef sc = parseScene(toughSlab(0, 4, 20), "tough-slab.json");
    Simulation sim(sc, SimulationOptions{1, false});
    sim.advance(0.3);
    const json rep = sim.report();
    EXPECT_FALSE(rep["blade"].contains("toughness"));
    // the geometric blade cuts as soon as its edge crosses elements: by 0.3 s (7 mm in) it has
    EXPECT_GT(rep["blade"]["cut_steps"].get<long>(), 0);
}

}  // namespace
}  // namespace cutsim
