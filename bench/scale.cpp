// `cutsim bench scale`: how each stage's cost per step grows with the mesh, on TetGen livers
// (`cutsim tetra` of the shipped surface) and MI lattices of the same surface, for four scenarios
// (sag, probe, scripted plane cuts, blade stroke), 1 and 2 threads, with memory per element.
#include "bench/bench.hpp"
#include "bench/options.hpp"
#include "app/commands.hpp"
#include "sim/scene.hpp"
#include "sim/simulation.hpp"
#include "sim/tetra.hpp"
#include "util/stopwatch.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

namespace cutsim::bench {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

struct ScaleArgs {
    bool json = false, tiny = false;
    std::string csv, plot;
    double maxElements = 1e5;  // largest mesh (about) [elements]
    int steps = 30;            // timed steps per run
    // one run in this process (the parent starts one process per run, so peak memory is its own)
    std::string one;
    int threads = 1;
};

// The liver as the shipped scenes set it up (inches to m, E 30 kPa, held behind z = -0.028 m,
// gravity -y), with its events at the first steps: the probe already 3 mm in, the four plane
// cuts of liver_cuts.json at t = 0, the blade's edge inside the liver moving down at 0.55 m/s.
json baseScene() {
    return json::parse(R"({
      "material": { "E": 30000, "nu": 0.3, "rho": 1000, "damping": 5.0 },
      "fixed": [ { "plane": { "point": [0, 0, -0.043], "normal": [0, 0, 1], "distance": 0.015 } } ],
      "loads": { "gravity": [0, -9.81, 0] },
      "integrator": { "scheme": "symplectic_euler",
                      "dt": { "mode": "fraction", "of": "exact", "fraction": 0.9, "on_limit": "clamp" } },
      "duration": 10,
      "capture": { "enabled": false },
      "output": { "vtu": false }
    })");
}

json scenario(const std::string& name, const json& object) {
    json j = baseScene();
    j["name"] = name;
    j["object"] = object;
    if (name == "probe") {
        j["tools"] = json::parse(R"([{ "name": "probe", "kind": "sphere", "radius": 0.01,
            "keyframes": [ { "time": 0, "position": [0.0, 0.137, 0.008] },
                           { "time": 10, "position": [0.0, 0.137, 0.008] } ] }])");
    } else if (name == "cuts") {
        j["cutting"] = json::parse(R"({ "cuts": [
            { "time": 0, "point": [-0.085, 0.06, 0.0], "normal": [1, 0, 0.15] },
            { "time": 0, "point": [-0.045, 0.06, 0.0], "normal": [1, 0.1, 0] },
            { "time": 0, "point": [-0.005, 0.06, 0.0], "normal": [1, -0.1, 0.1] },
            { "time": 0, "point": [0.0, 0.09, 0.0], "normal": [0.1, 1, 0] } ] })");
    } else if (name == "blade") {
        // the after-cut exact eigen-solve per blade step is left out (exact_after_cut false)
        j["cutting"] = {{"exact_after_cut", false}};
        j["integrator"]["min_stretch"] = 0.2;
        j["tools"] = json::parse(R"([{ "name": "scalpel", "kind": "blade", "size": [0.2, 0.03, 0.001],
            "keyframes": [ { "time": 0, "position": [-0.037, 0.10, 0.02] },
                           { "time": 0.3, "position": [-0.037, -0.065, 0.02] } ] }])");
    }
    return j;
}

double residentBytes() {
    std::ifstream f("/proc/self/statm");
    long pages = 0, resident = 0;
    f >> pages >> resident;
    return static_cast<double>(resident) * static_cast<double>(::sysconf(_SC_PAGESIZE));
}

// One run: build, then `steps` steps; per-step seconds of each stage, set-up seconds, memory.
int runOne(const ScaleArgs& a) {
    const double rss0 = residentBytes();
    const SceneDef def = loadScene(a.one);
    Simulation::Options o;
    o.threads = a.threads;
    Stopwatch setup;
    Simulation sim(def, o);
    const double setupSeconds = setup.seconds();
    const StageTimes before = sim.record().stages;
    Stopwatch wall;
    long steps = 0;
    while (steps < a.steps && sim.status() == RunStatus::Running) sim.step(), ++steps;
    const double seconds = wall.seconds();
    struct rusage ru {};
    ::getrusage(RUSAGE_SELF, &ru);
    json stages = json::object();
    for (int s = 0; s < kStages; ++s) {
        const Stage st = static_cast<Stage>(s);
        if (st == Stage::Render || st == Stage::Encode) continue;
        stages[stageName(st)] = (sim.record().stages[st] - before[st]) / double(std::max(1L, steps));
    }
    const int elements = sim.record().initial.value("elements", 0);
    json j = {{"elements", elements},
              {"elements_final", sim.model().elements()},
              {"status", runStatusName(sim.status())},
              {"steps", steps},
              {"dt", sim.dt()},
              {"setup_seconds", setupSeconds},
              {"seconds_per_step", seconds / double(std::max(1L, steps))},
              {"stages", stages},
              {"cuts", sim.record().cutsMade},
              {"blade_cut_steps", sim.record().bladeCutSteps},
              {"bytes_per_element", (1024.0 * static_cast<double>(ru.ru_maxrss) - rss0) / std::max(1, elements)}};
    std::cout << j.dump() << "\n";
    return sim.status() == RunStatus::Running ? 0 : 1;
}

// Least-squares slope of log y against log x: the exponent of y ~ x^p.
double fitExponent(const std::vector<double>& x, const std::vector<double>& y) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    int n = 0;
    for (size_t i = 0; i < x.size(); ++i) {
        if (!(x[i] > 0) || !(y[i] > 0)) continue;
        const double lx = std::log(x[i]), ly = std::log(y[i]);
        sx += lx, sy += ly, sxx += lx * lx, sxy += lx * ly, ++n;
    }
    if (n < 2) return NAN;
    return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

// A liver of the scale runs: a TetGen mesh of target edge length `size` or an MI lattice of `cells`.
struct MeshDef {
    std::string kind;  // tetgen | mi
    double size = 0;
    int cells = 0;
    double estimate = 0;  // elements, about
};

// Target edge lengths of the TetGen livers and lattice cells of the MI livers, up to about 1M
// elements (a factor of 3-4 apart), those up to --max-elements.
std::vector<MeshDef> scaleMeshes(const ScaleArgs& a) {
    std::vector<MeshDef> meshes;
    // (TetGen keeps the surface's 274 triangles: its coarsest liver has about 8k tets)
    const std::vector<std::pair<double, double>> tetra = {{0.03, 8e3},  {0.01, 2e4},  {0.005, 8e4},
                                                          {0.003, 3e5}, {0.002, 6e5}, {0.0016, 1.2e6}};
    const std::vector<std::pair<int, double>> lattice = {{10, 1.5e3}, {16, 6e3},   {25, 2.3e4},
                                                         {40, 9e4},   {63, 3.5e5}, {100, 1.4e6}};
    for (const auto& [h, n] : tetra)
        if (n <= a.maxElements && (!a.tiny || n < 1e4)) meshes.push_back({"tetgen", h, 0, n});
    for (const auto& [c, n] : lattice)
        if (n <= a.maxElements && (!a.tiny || n < 2e3)) meshes.push_back({"mi", 0, c, n});
    return meshes;
}

// The scene's `object` for a mesh of the liver surface. A TetGen liver is built once here and
// cached (object.tetra's cache), so the runs read it.
json meshObject(const MeshDef& m, const std::string& surface, double scale, bool quiet) {
    if (m.kind != "tetgen") return {{"surface", {{"path", surface}, {"cells", m.cells}}}, {"scale", scale}};
    TetraOptions to;
    to.size = m.size;
    to.material = Material{30000, 0.3, 1000};
    to.mesher = Mesher::TetGen;  // the sizes above are TetGen's
    bool cached = false;
    TetraReport rep;
    std::string file;
    Stopwatch sw;
    tetraCached(surface, scale, to, cached, rep, file);
    if (!quiet)
        std::fprintf(stderr, "tetra --size %g: %s in %.1f s\n", m.size, cached ? "cached" : "built", sw.seconds());
    return {{"tetra", {{"surface", surface}, {"size", m.size}, {"mesher", "tetgen"}}}, {"scale", scale}};
}

// One run in a process of its own (`bench scale --one`), so that its peak memory is its own: its
// JSON line, or {status: failed, error: its stderr}.
json runInChild(const std::string& self, const fs::path& work, const fs::path& scene, int threads, int steps) {
    const std::string cmd = "'" + self + "' bench scale --one '" + scene.string() + "' --threads " +
                            std::to_string(threads) + " --steps " + std::to_string(steps) + " 2>'" +
                            (work / "err.txt").string() + "'";
    FILE* p = ::popen(cmd.c_str(), "r");
    if (!p) throw std::runtime_error("cannot start " + self);
    std::string out;
    char buf[4096];
    while (std::fgets(buf, sizeof buf, p)) out += buf;
    ::pclose(p);  // a failed run shows in its output
    try {
        return json::parse(out);
    } catch (const json::exception&) {
        std::ifstream e(work / "err.txt");
        std::string err((std::istreambuf_iterator<char>(e)), std::istreambuf_iterator<char>());
        return {{"status", "failed"}, {"error", err}};
    }
}

void printScaleHeader() {
    std::printf("%-7s %8s %-6s %7s %10s %10s %10s %10s %10s %10s %10s %8s %s\n", "mesh", "elements", "scene", "threads",
                "step [ms]", "forces", "integrate", "contact", "cut", "timestep", "setup [s]", "B/elem", "status");
}

void printScaleRun(const json& r) {
    const std::string kind = r["mesh"].get<std::string>(), sname = r["scene"].get<std::string>();
    const int threads = r["threads"].get<int>();
    if (!r.contains("stages")) {
        std::printf("%-7s %8s %-6s %7d failed: %s\n", kind.c_str(), "?", sname.c_str(), threads,
                    r.value("error", std::string()).c_str());
        return;
    }
    const json& st = r["stages"];
    std::printf("%-7s %8d %-6s %7d %10.4f %10.4f %10.4f %10.4f %10.4f %10.4f %10.2f %8.0f %s\n", kind.c_str(),
                r["elements"].get<int>(), sname.c_str(), threads, 1e3 * r["seconds_per_step"].get<double>(),
                1e3 * st["forces"].get<double>(), 1e3 * st["integrate"].get<double>(),
                1e3 * st["contact"].get<double>(), 1e3 * st["cut"].get<double>(), 1e3 * st["timestep"].get<double>(),
                r["setup_seconds"].get<double>(), r["bytes_per_element"].get<double>(),
                r["status"].get<std::string>().c_str());
    std::fflush(stdout);
}

// Fitted exponents: stage cost per step ~ elements^p, per mesh kind, scene and thread count,
// over the stages that cost something.
json fitScaleExponents(const json& runs, const std::vector<std::string>& scenarios) {
    json fits = json::array();
    for (const std::string kind : {"tetgen", "mi"})
        for (const std::string& sname : scenarios)
            for (int threads : {1, 2}) {
                std::map<std::string, std::pair<std::vector<double>, std::vector<double>>> pts;
                for (const auto& r : runs) {
                    if (r["mesh"] != kind || r["scene"] != sname || r["threads"] != threads || !r.contains("stages"))
                        continue;
                    const double n = r["elements"].get<double>();
                    pts["step"].first.push_back(n);
                    pts["step"].second.push_back(r["seconds_per_step"].get<double>());
                    for (auto& [k, v] : r["stages"].items()) {
                        pts[k].first.push_back(n);
                        pts[k].second.push_back(v.get<double>());
                    }
                    pts["setup"].first.push_back(n);
                    pts["setup"].second.push_back(r["setup_seconds"].get<double>());
                }
                json e = json::object();
                for (auto& [k, xy] : pts) {
                    const double p = fitExponent(xy.first, xy.second);
                    if (std::isfinite(p)) e[k] = std::round(p * 100) / 100;
                }
                if (!e.empty())
                    fits.push_back({{"mesh", kind}, {"scene", sname}, {"threads", threads}, {"exponents", e}});
            }
    return fits;
}

void writeScaleCsv(const json& runs, const std::string& path) {
    json timed = json::array();
    for (const auto& r : runs)
        if (r.contains("stages")) timed.push_back(r);
    writeCsv(path, timed,
             {"mesh", "elements", "scene", "threads", "status", "steps", "seconds_per_step", "stages/loads",
              "stages/contact", "stages/cut", "stages/forces", "stages/integrate", "stages/checks", "stages/timestep",
              "setup_seconds", "bytes_per_element"});
}

// Seconds per step against elements on one thread, log-log: a line per scene and mesh kind.
void plotScale(const json& runs, const std::vector<std::string>& scenarios, const std::string& out) {
    if (!haveGnuplot()) throw InputError("--plot needs gnuplot (Debian package gnuplot-nox)");
    const std::string dir = plotDataDir("scale");
    std::ostringstream g;
    g << "set logscale xy\nset xlabel 'elements'\nset ylabel 'seconds per step, 1 thread'\nset key top left\nset "
         "grid\n"
         "set format y '%.0e'\nplot ";
    bool first = true;
    int pt = 5;
    for (const std::string& sname : scenarios)
        for (const std::string kind : {"tetgen", "mi"}) {
            const std::string file = dir + "/" + sname + "_" + kind + ".dat";
            std::ofstream d(file);
            int rows = 0;
            for (const auto& r : runs)
                if (r["mesh"] == kind && r["scene"] == sname && r["threads"] == 1 && r.contains("stages"))
                    d << r["elements"] << ' ' << r["seconds_per_step"] << '\n', ++rows;
            if (rows == 0) continue;
            g << (first ? "" : ", ") << "'" << file << "' using 1:2 with linespoints pt " << pt++ << " dt "
              << (kind == "mi" ? 2 : 1) << " title '" << sname << ", " << kind << "'";
            first = false;
        }
    g << "\n";
    runGnuplot(dir, "set terminal pngcairo size 900,600 font ',10' noenhanced", g.str(), out);
}

int runScale(const ScaleArgs& a) {
    if (!a.one.empty()) return runOne(a);
    // the SOFA liver surface (shipped as assets/meshes/sofa_liver.obj)
    const std::string surface = std::string(CUTSIM_DATA_DIR) + "/surface/sofa_liver.obj";
    if (!fs::exists(surface)) throw InputError(surface, 0, "the liver surface is missing");
    const double scale = 0.0254;
    const std::vector<MeshDef> meshes = scaleMeshes(a);
    const std::vector<std::string> scenarios =
        a.tiny ? std::vector<std::string>{"sag", "cuts"} : std::vector<std::string>{"sag", "probe", "cuts", "blade"};

    const fs::path work = fs::temp_directory_path() / ("cutsim-bench-scale-" + std::to_string(::getpid()));
    fs::create_directories(work);
    const std::string self = fs::read_symlink("/proc/self/exe").string();
    json runs = json::array();
    if (!a.json) printScaleHeader();
    for (const MeshDef& m : meshes) {
        const json object = meshObject(m, surface, scale, a.json);
        for (const std::string& sname : scenarios) {
            const fs::path scene = work / (sname + ".json");
            std::ofstream(scene) << scenario(sname, object).dump(1);
            for (int threads : {1, 2}) {
                json r = runInChild(self, work, scene, threads, a.steps);
                r["mesh"] = m.kind;
                r["scene"] = sname;
                r["threads"] = threads;
                if (m.kind == "tetgen")
                    r["size"] = m.size;
                else
                    r["cells"] = m.cells;
                runs.push_back(r);
                if (!a.json) printScaleRun(r);
            }
        }
    }
    fs::remove_all(work);

    const json fits = fitScaleExponents(runs, scenarios);
    if (!a.csv.empty()) writeScaleCsv(runs, a.csv);
    if (!a.plot.empty()) plotScale(runs, scenarios, a.plot);
    if (a.json) {
        printJson({{"steps", a.steps}, {"runs", runs}, {"exponents", fits}});
        return 0;
    }
    std::printf("\nexponents p of cost per step ~ elements^p (threads 1 and 2):\n");
    for (const auto& f : fits)
        std::printf("  %-7s %-6s %d  %s\n", f["mesh"].get<std::string>().c_str(), f["scene"].get<std::string>().c_str(),
                    f["threads"].get<int>(), f["exponents"].dump().c_str());
    return 0;
}

void scaleOptions(CLI::App& c, ScaleArgs& a) {
    jsonFlag(c, a.json,
             "{steps, runs: [{mesh, size|cells, scene, threads, elements, status, seconds_per_step, "
             "stages (seconds per step), setup_seconds, bytes_per_element, ...}], exponents: [{mesh, scene, "
             "threads, exponents: {stage: p}}]}");
    csvOption(c, a.csv, "runs");
    c.add_option("--plot", a.plot, "Draw seconds per step against elements, log-log, to this PNG (gnuplot)");
    c.add_option("--max-elements", a.maxElements,
                 "Largest meshes, about (default 1e5: up to about 90k elements; 1.5e6 adds the 280k to 1.2M "
                 "meshes, minutes each and a few GB)")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    c.add_option("--steps", a.steps, "Timed steps per run")->check(CLI::Range(1, 100000))->capture_default_str();
    tinyFlag(c, a.tiny, "the coarsest meshes, sag and cuts");
    c.add_option("--one", a.one, "Run one scene and print its JSON line (what the runs above start)")->group("");
    threadsOption(c, a.threads, "Threads of --one", 1)->group("");
}

}  // namespace

void addScaleBench() {
    addSubcommand("scale",
                  "How each stage's cost per step grows with the mesh: sag, probe, scripted plane cuts and a blade "
                  "stroke on TetGen livers (cutsim tetra of the shipped surface) and MI lattices, 1 and 2 threads, "
                  "memory per element, fitted exponents",
                  scaleOptions, runScale);
}

}  // namespace cutsim::bench
