// `cutsim bench contact`: what the contact stage costs against the number of contact points, with
// the tool pressing or away from the tissue, and how deep the tool sinks against its stiffness.
// The object is a soft slab (10 x 10 x 2 cm, E 30 kPa) fixed at its bottom, pressed 2 mm at the
// middle of its top by a 1 cm sphere; contact.spacing sets the number of points (1 m: the
// surface's vertices only).
#include "bench/bench.hpp"
#include "bench/machine.hpp"
#include "bench/options.hpp"
#include "app/commands.hpp"
#include "sim/scene.hpp"
#include "sim/simulation.hpp"
#include "util/stopwatch.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <fstream>
#include <sstream>
#include <memory>
#include <string>
#include <vector>

namespace cutsim::bench {

namespace {

using nlohmann::json;

struct ContactArgs {
    bool json = false;
    bool tiny = false;
    int threads = 1;
    std::string plot;  // PNG of the table
    std::string csv;   // the runs as CSV
};

constexpr double kRadius = 0.01;  // probe [m]
constexpr double kDepth = 0.002;  // pressed into the top [m]

// penalty: contact.model "penalty" (the stiffness sweep); else the default, projection
json slabScene(int cells, double spacing, bool near, double stiffness, double duration, bool penalty) {
    const double top = 0.02;
    const double z = near ? top + kRadius - kDepth : top + 0.1;
    json probe = {{"name", "probe"},
                  {"kind", "sphere"},
                  {"radius", kRadius},
                  {"keyframes", json::array({{{"time", 0.0}, {"position", {0.05, 0.05, near ? top + kRadius : z}}},
                                             {{"time", 0.3 * duration}, {"position", {0.05, 0.05, z}}}})}};
    if (stiffness > 0) probe["stiffness"] = stiffness;
    return {{"name", "contact-bench"},
            {"object", {{"box", {{"size", {0.1, 0.1, top}}, {"cells", {cells, cells, std::max(1, cells / 5)}}}}}},
            {"material", {{"E", 30000}, {"nu", 0.3}, {"rho", 1000}, {"damping", 20.0}}},
            {"fixed", json::array({{{"plane", {{"point", {0, 0, 0}}, {"normal", {0, 0, 1}}, {"distance", 1e-4}}}}})},
            {"loads", {{"gravity", {0, 0, 0}}}},
            {"integrator",
             {{"scheme", "symplectic_euler"}, {"dt", {{"mode", "fraction"}, {"of", "exact"}, {"fraction", 0.8}}}}},
            {"tools", json::array({probe})},
            {"contact", {{"spacing", spacing}, {"model", penalty ? "penalty" : "projection"}}},
            {"duration", duration},
            {"capture", {{"enabled", false}}},
            {"output", {{"vtu", false}}}};
}

struct ContactRow {
    double spacing = 0;
    bool near = false;
    double stiffnessFraction = 0;  // of the stable limit; 0: the default
    int points = 0, tets = 0;
    long steps = 0;
    double contactPerStep = 0, elasticPerStep = 0;  // [s]
    double stiffness = 0, limit = 0;                // [N/m]
    double maxDepth = 0, force = 0;                 // [m], final |reaction| [N]
    int contacts = 0;
    std::string status;  // the report's: "ok", or why the run stopped
};

ContactRow runContactRow(int cells, double spacing, bool near, double fraction, double duration, int threads) {
    ContactRow r;
    r.spacing = spacing;
    r.near = near;
    r.stiffnessFraction = fraction;
    Simulation::Options so;
    so.threads = threads;
    double stiffness = 0;
    if (fraction > 0) {  // the limit of this surface first, then the tool at that share of it
        Simulation probe(parseScene(slabScene(cells, spacing, near, 0, duration, true), "contact-bench"), so);
        stiffness = fraction * probe.contactSettings().stiffnessLimit;
    }
    Simulation sim(parseScene(slabScene(cells, spacing, near, stiffness, duration, fraction > 0), "contact-bench"), so);
    while (sim.status() == RunStatus::Running && !sim.finished()) sim.step();
    sim.finish();
    r.status = sim.report()["status"].get<std::string>();
    const RunRecord& rec = sim.record();
    r.steps = sim.state().steps;
    const double n = std::max<double>(1, static_cast<double>(r.steps));
    r.contactPerStep = rec.stages[Stage::Contact] / n;
    r.elasticPerStep = (rec.stages[Stage::Forces] + rec.stages[Stage::Integrate]) / n;
    r.points = sim.contact()->points().points();
    r.tets = static_cast<int>(sim.model().tets.cols());
    r.stiffness = sim.contact()->tools()[0].stiffness;
    r.limit = sim.contactSettings().stiffnessLimit;
    r.maxDepth = rec.tool.maxDepth;
    r.force = sim.contact()->last().reaction[0].norm();
    r.contacts = sim.contact()->last().contacts;
    return r;
}

// Left: contact and elastic stage time per step against the contact points, tool pressing and
// away; right: deepest point and force against the penalty stiffness.
void plotRows(const std::vector<ContactRow>& rows, const std::string& out) {
    const std::string dir = plotDataDir("contact_plot");
    {
        std::ofstream away(dir + "/away.dat"), press(dir + "/pressing.dat"), sweep(dir + "/sweep.dat");
        for (const ContactRow& r : rows) {
            if (r.stiffnessFraction > 0)
                sweep << r.stiffness / r.limit << " " << r.maxDepth * 1e3 << " " << r.force << "\n";
            else
                (r.near ? press : away) << r.points << " " << r.contactPerStep * 1e6 << " " << r.elasticPerStep * 1e6
                                        << "\n";
        }
    }
    std::ostringstream g;
    g << "set multiplot layout 1,2\nset grid\n"
      << "set title 'cost per step, projection contact'\nset logscale xy\nset xlabel 'contact points'\n"
      << "set ylabel 'stage time per step [us]'\nset key bottom right\nset xrange [700:200000]\n"
      << "plot '" << dir << "/pressing.dat' using 1:2 with linespoints lw 2 pt 7 title 'contact, tool pressing', '"
      << dir << "/away.dat' using 1:2 with linespoints lw 2 pt 5 title 'contact, tool away', '" << dir
      << "/pressing.dat' using 1:3 with linespoints lw 2 pt 9 dt 2 title 'forces + integrate'\n"
      << "unset logscale\nset autoscale x\nset title 'penalty model against its stiffness'\nset xlabel 'k / k_max'\n"
      << "set ylabel 'deepest point [mm]'\nset y2label 'force [N]'\nset ytics nomirror\nset y2tics\n"
      << "set yrange [0:*]\nset y2range [0:*]\nset key top center\n"
      << "plot '" << dir << "/sweep.dat' using 1:2 with linespoints lw 2 pt 7 title 'deepest point', '" << dir
      << "/sweep.dat' using 1:3 axes x1y2 with linespoints lw 2 pt 5 title 'force'\n"
      << "unset multiplot\n";
    runGnuplot(dir, "set terminal pngcairo size 1200,480 noenhanced", g.str(), out);
}

int runContact(const ContactArgs& a) {
    const json machine = machineJson();
    if (!a.plot.empty() && !haveGnuplot())
        throw InputError("--plot needs gnuplot, which is not installed (Debian package gnuplot-nox)");
    const int cells = a.tiny ? 10 : 20;
    const double duration = a.tiny ? 0.02 : 0.1;
    const std::vector<double> spacings =
        a.tiny ? std::vector<double>{0.004} : std::vector<double>{1.0, 0.005, 0.0028, 0.0016, 0.0009, 0.00075};
    std::vector<ContactRow> rows;
    for (double s : spacings)
        for (bool near : {false, true}) {
            rows.push_back(runContactRow(cells, s, near, 0, duration, a.threads));
            if (!a.json)
                std::fprintf(stderr, "  spacing %.4g m, %s: %d points\n", s, near ? "pressing" : "away",
                             rows.back().points);
        }
    const double sweepSpacing = a.tiny ? 0.004 : 0.0028;
    for (double f : {0.1, 0.25, 0.5, 1.0})
        rows.push_back(runContactRow(cells, sweepSpacing, true, f, duration, a.threads));
    json j = json::array();
    for (const ContactRow& r : rows)
        j.push_back({{"spacing", r.spacing},
                     {"tool", r.near ? "pressing" : "away"},
                     {"stiffness_fraction", r.stiffnessFraction},
                     {"points", r.points},
                     {"tets", r.tets},
                     {"steps", r.steps},
                     {"contact_seconds_per_step", r.contactPerStep},
                     {"elastic_seconds_per_step", r.elasticPerStep},
                     {"stiffness", jsonNumber(r.stiffness)},
                     {"stiffness_limit", jsonNumber(r.limit)},
                     {"max_depth", r.maxDepth},
                     {"final_force", r.force},
                     {"final_contacts", r.contacts},
                     {"status", r.status}});
    if (!a.plot.empty()) plotRows(rows, a.plot);
    if (!a.csv.empty())
        writeCsv(a.csv, j,
                 {"spacing", "tool", "stiffness_fraction", "points", "tets", "steps", "contact_seconds_per_step",
                  "elastic_seconds_per_step", "stiffness", "stiffness_limit", "max_depth", "final_force",
                  "final_contacts", "status"});
    if (a.json) {
        printResult(json{{"probe_radius", kRadius}, {"pressed", kDepth}, {"runs", j}}, machine);
        for (const ContactRow& r : rows)
            if (r.status != "ok") return 1;
        return 0;
    }
    std::printf("slab 10 x 10 x 2 cm, E 30 kPa, probe radius %.0f mm pressed %.0f mm, 1 thread per run\n",
                kRadius * 1e3, kDepth * 1e3);
    std::printf("%9s %9s %7s %7s %12s %12s %8s %10s %10s %10s %8s\n", "spacing", "tool", "k/kmax", "points",
                "contact[us]", "elastic[us]", "ratio", "k [N/m]", "depth[mm]", "force [N]", "touching");
    int failed = 0;
    for (const ContactRow& r : rows)
        std::printf("%9.4g %9s %7.2f %7d %12.2f %12.2f %8.3f %10.4g %10.3f %10.4f %8d\n", r.spacing,
                    r.near ? "pressing" : "away", r.stiffness / r.limit, r.points, r.contactPerStep * 1e6,
                    r.elasticPerStep * 1e6, r.contactPerStep / r.elasticPerStep, r.stiffness, r.maxDepth * 1e3, r.force,
                    r.contacts);
    for (const ContactRow& r : rows)
        if (r.status != "ok") {
            std::printf("spacing %.4g m, %s, k/kmax %.2f: %s\n", r.spacing, r.near ? "pressing" : "away",
                        r.stiffness / r.limit, r.status.c_str());
            ++failed;
        }
    std::printf("(contact and elastic: stage seconds per step, elastic = forces + integrate; ratio = contact / "
                "elastic; depth: deepest point over the run)\n");
    return failed ? 1 : 0;
}

void contactOptions(CLI::App& c, ContactArgs& a) {
    jsonFlag(c, a.json, "{probe_radius, pressed, runs: [...]}", true);
    tinyFlag(c, a.tiny, "one small slab");
    csvOption(c, a.csv, "runs");
    plotOption(c, a.plot, "cost against contact points and depth and force against stiffness");
    threadsOption(c, a.threads, "Worker threads per run", 1)->capture_default_str();
}

}  // namespace

void addContactBench() {
    addSubcommand("contact",
                  "Contact cost per step against contact points (tool pressing or away), and "
                  "penetration and force against the penalty stiffness",
                  contactOptions, runContact);
}

}  // namespace cutsim::bench
