// `cutsim bench improve`: the mesh improver against TetGen's and Gmsh's optimisers and CGAL's
// mesher on the same meshes (thesis Table 5.1), the step gained against time, and what the improvement does to the
// physics (the liver's sag, a bar's first frequency).
#include "bench/bench.hpp"
#include "bench/machine.hpp"
#include "bench/options.hpp"
#include "app/commands.hpp"

#include "cut/remesh.hpp"
#include "fem/integrate.hpp"
#include "improve/improve.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "timestep/modes.hpp"
#include "timestep/timestep.hpp"
#include "util/stopwatch.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "util/input_error.hpp"

#include <algorithm>
#include <cerrno>
#include <optional>
#include <climits>
#include <cstring>
#include <map>
#include <sys/wait.h>
#include <unistd.h>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>

namespace cutsim::bench {
namespace {

using json = nlohmann::json;

struct ImproveBenchArgs {
    bool json = false, tiny = false;
    double seconds = 10;  // longest run of the gain-against-time table [s]
    std::string plot;
    // --speed: the improver's time at its defaults instead, per mesh and thread count
    bool speed = false;
    std::vector<std::string> speedMeshes{"armadillo", "knight"};
    std::vector<int> threads{1, 2};
    int rounds = 3, busyRounds = 1;
};

// The tet meshes of the data folder at the scales the project uses them (the .gmsh22 copies are
// the same meshes).
struct MeshCase {
    const char* name;
    const char* file;
    double scale;
};
constexpr MeshCase kCases[] = {{"liver", "tet/sofa_liver.msh", 0.0254},
                               {"liver2", "tet/sofa_liver2.msh", 0.1},
                               {"armadillo", "tet/sofa_Armadillo_Tetra_4406.vtu", 0.01},
                               {"knight", "tet/igltests_decimated-knight.mesh", 1},
                               {"octopus", "tet/igl_octopus-low.mesh", 1}};

// One method's result on one mesh.
json resultJson(const TetMesh& before, const MeshStepStats& b, const TetMesh& after, const Material& mat,
                double seconds) {
    const MeshStepStats a = meshStepStats(after, mat);
    const Eigen::Vector3d lo = before.X.rowwise().minCoeff(), hi = before.X.rowwise().maxCoeff();
    return {{"dt_exact", a.dtExact},
            {"gain", a.dtExact / b.dtExact},
            {"tets", a.tets},
            {"min_dihedral_deg", a.minDihedralDeg},
            {"volume_change", (a.volume - b.volume) / b.volume},
            {"boundary_distance_rel", surfaceDistance(before, after) / (hi - lo).norm()},
            {"seconds", seconds}};
}

// A baseline in its own executable next to cutsim (Gmsh 4.8 carries symbols that clash with
// TetGen's in one process; CGAL's templates stay out of every other build): exe IN OUT [arg].
TetMesh runHelper(const std::string& name, const TetMesh& mesh, const std::string& arg, const std::string& what) {
    namespace fs = std::filesystem;
    const fs::path exe = fs::read_symlink("/proc/self/exe").parent_path() / name;
    if (!fs::exists(exe)) throw std::runtime_error(name + " not built");
    const fs::path dir = fs::temp_directory_path() / ("cutsim_" + name + "_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const std::string in = (dir / "in.msh").string(), out = (dir / "out.msh").string();
    writeMsh22(in, mesh);
    const std::string cmd = "'" + exe.string() + "' '" + in + "' '" + out + "' '" + arg + "' 2>/dev/null >/dev/null";
    const int rc = std::system(cmd.c_str());
    if (rc != 0 || !fs::exists(out)) {
        fs::remove_all(dir);
        throw std::runtime_error(what + " failed");
    }
    TetMesh r = readTetMesh(out);
    fs::remove_all(dir);
    return r;
}

// Runs a baseline; a failure becomes {"error": message}, never a missing row.
json baseline(const TetMesh& mesh, const MeshStepStats& b, const Material& mat,
              const std::function<TetMesh(const TetMesh&)>& run) {
    try {
        const auto t0 = WallClock::now();
        const TetMesh out = run(mesh);
        const double s = secondsSince(t0);
        return resultJson(mesh, b, out, mat, s);
    } catch (const std::exception& e) {
        return {{"error", e.what()}};
    }
}

// Best exact step reached by the time t, from an improver's history.
double bestBy(const ImproveReport& r, double t) {
    double best = 0;
    for (const auto& p : r.history)
        if (p.seconds <= t) best = std::max(best, p.dtExact);
    return best;
}

// The liver sag of `bench accuracy` on the input and the improved mesh: static equilibrium error
// at the input's nodes against the input refined twice, and explicit cost per simulated second at
// 0.9 of each mesh's exact step.
json liverSag(bool tiny, bool quiet) {
    const TetMesh inches = readTetMesh(std::string(CUTSIM_DATA_DIR) + "/tet/sofa_liver.msh");
    const int refLevel = tiny ? 1 : 2;
    int steps = 0;
    const Model ref = liverModel(inches, refLevel, 0);
    const Eigen::Matrix3Xd uRef = liverEquilibrium(ref, &steps) - ref.X;
    const int n0 = inches.nodes();
    const Model coarse = liverModel(inches, 0, 0);

    // The improved mesh, its clamped nodes held (they are the same nodes, so they select again).
    TetMesh meters = inches;
    meters.X *= 0.0254;
    ImproveOptions o;
    for (int i = 0; i < coarse.nodes(); ++i)
        if (coarse.fixed[i]) o.fixedNodes.push_back(i);
    o.collapse = false;  // node i stays node i, for the error at the input's nodes
    improveMesh(meters, o);
    TetMesh improvedInches = meters;
    improvedInches.X /= 0.0254;

    json rows = json::array();
    for (int k = 0; k < 2; ++k) {
        const Model m = liverModel(k ? improvedInches : inches, 0, 0);
        const Eigen::Matrix3Xd u = liverEquilibrium(m, &steps) - m.X;
        // Error at the input's free nodes: the improved mesh's node i moved, so its displacement
        // is compared with the reference's at the same node (their rest positions differ by the
        // improvement's motion, at most a few millimetres on the surface).
        double num = 0, den = 0;
        for (int i = 0; i < n0; ++i) {
            if (coarse.fixed[i]) continue;
            num += (u.col(i) - uRef.col(i)).squaredNorm();
            den += uRef.col(i).squaredNorm();
        }
        Model dyn = m;
        dyn.massDamping = 5;
        const double dt = 0.9 * exactCriticalDt(dyn).dt;
        State s = makeState(dyn);
        Stepper st;
        const int n = tiny ? 200 : 2000;
        const auto t0 = WallClock::now();
        for (int j = 0; j < n; ++j) st.step(dyn, s, StepOptions{Integrator::SymplecticEuler, dt});
        const double wall = secondsSince(t0);
        rows.push_back({{"mesh", k ? "improved" : "input"},
                        {"tets", m.elements()},
                        {"dt", dt},
                        {"error", std::sqrt(num / den)},
                        {"wall_per_sim_second", wall / (n * dt)},
                        {"finite", s.x.allFinite()}});
        if (!quiet) std::fprintf(stderr, "  liver sag %s done\n", k ? "improved" : "input");
    }
    return rows;
}

// A cantilever (1 x 0.1 x 0.1 m, 30 x 3 x 3 cubes) with its interior nodes jittered by up to 0.35
// of the spacing, clamped at x = 0: its first frequency before and after improvement, against the
// unjittered bar's.
json barFrequency() {
    const double L = 1, h = 0.1;
    const int nx = 30, ny = 3;
    TetMesh mesh = boxMesh(L, h, h, nx, ny, ny);
    const Material mat{1e6, 0.3, 1000};
    auto build = [&](const TetMesh& t) {
        Model m = buildModel(t, mat);
        for (int i = 0; i < m.nodes(); ++i) m.fixed[i] = m.X(0, i) < 1e-9;
        updateMasses(m);
        return m;
    };
    const double fRegular = lowestFrequency(build(mesh));
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-0.35, 0.35);
    const double s = h / ny;
    for (int i = 0; i < mesh.nodes(); ++i) {
        const Eigen::Vector3d p = mesh.X.col(i);
        if (p.x() < 1e-9 || p.x() > L - 1e-9 || p.y() < 1e-9 || p.y() > h - 1e-9 || p.z() < 1e-9 || p.z() > h - 1e-9)
            continue;
        mesh.X.col(i) = p + s * Eigen::Vector3d(u(rng), u(rng), u(rng));
    }
    const Model before = build(mesh);
    ImproveOptions o;
    o.material = mat;
    o.featureAngleDeg = 30;  // a box: edges and corners kept
    for (int i = 0; i < before.nodes(); ++i)
        if (before.fixed[i]) o.fixedNodes.push_back(i);
    TetMesh improved = mesh;
    const ImproveReport r = improveMesh(improved, o);
    const Model after = build(improved);
    const double f0 = lowestFrequency(before), f1 = lowestFrequency(after);
    return {{"tets", before.elements()},
            {"f_regular", fRegular},
            {"f_jittered", f0},
            {"f_improved", f1},
            {"frequency_change", (f1 - f0) / f0},
            {"dt_jittered", exactCriticalDt(before).dt},
            {"dt_improved", exactCriticalDt(after).dt},
            {"gain", r.after.dtExact / r.before.dtExact}};
}

void drawPlot(const std::string& out, const json& timing) {
    const std::string dir = plotDataDir("improve_plot");
    std::ostringstream g;
    g << "set logscale x\nset xlabel 'seconds (one core)'\nset ylabel 'exact step of the mesh kept / input step'\n"
      << "set key left top\nset grid\nplot ";
    int k = 0;
    for (const auto& [name, t] : timing.items()) {
        const std::string dat = dir + "/" + name + ".dat";
        std::ofstream d(dat);
        double best = 0;  // the mesh kept so far
        for (const auto& p : t["history"]) {
            best = std::max(best, p[1].get<double>());
            d << std::max(1e-3, p[0].get<double>()) << " " << best << "\n";
        }
        g << (k++ ? ", " : "") << "'" << dat << "' with steps lw 2 title '" << name << "'";
    }
    g << "\n";
    runGnuplot(dir, "set terminal pngcairo size 900,560", g.str(), out);
}

const MeshCase& meshCase(const std::string& name) {
    for (const MeshCase& c : kCases)
        if (name == c.name) return c;
    std::string known;
    for (const MeshCase& c : kCases) known += std::string(known.empty() ? "" : ", ") + c.name;
    throw InputError("--speed-meshes: no mesh '" + name + "' (known: " + known + ")");
}

// --speed: cutsim's improver at its defaults (as `cutsim improve MESH --scale S --threads K`), its
// seconds.total per mesh and thread count; the runs take turns (meshes and counts, the order
// reversed every other round), `rounds` of them idle, then `busyRounds` with another core busy.
int runImproveSpeed(const ImproveBenchArgs& a) {
    const json machine = machineJson();
    const Material mat;
    std::vector<const MeshCase*> cases;
    for (const std::string& name : a.speedMeshes) cases.push_back(&meshCase(name));
    if (a.threads.empty()) throw InputError("--threads: no thread count");
    std::vector<std::pair<size_t, int>> order;  // (case, threads)
    for (size_t k = 0; k < cases.size(); ++k)
        for (int th : a.threads) order.emplace_back(k, th);
    std::vector<TetMesh> meshes;
    for (const MeshCase* c : cases) {
        ReadOptions ro;
        ro.scale = c->scale;
        meshes.push_back(readTetMesh(std::string(CUTSIM_DATA_DIR) + "/" + c->file, ro));
    }
    json runs = json::array();
    if (!a.json)
        std::printf("%-10s %6s %7s %5s %5s %9s %8s %6s\n", "mesh", "tets", "threads", "load", "round", "seconds",
                    "gain", "load1");
    for (int r = 0; r < a.rounds + a.busyRounds; ++r) {
        const bool busy = r >= a.rounds;
        std::optional<BusyCore> spin;
        if (busy) spin.emplace();
        std::vector<std::pair<size_t, int>> turn = order;
        if (r % 2) std::reverse(turn.begin(), turn.end());
        for (const auto& [k, th] : turn) {
            const MeshCase* c = cases[k];
            const TetMesh& input = meshes[k];
            TetMesh m = input;
            ImproveOptions o;
            o.material = mat;
            o.threads = th;
            const json load = loadAverage();
            const ImproveReport rep = improveMesh(m, o);
            double total = 0;
            for (const auto& [stage, v] : rep.seconds)
                if (stage == "total") total = v;
            json row = {{"mesh", c->name},
                        {"tets", input.elements()},
                        {"threads", th},
                        {"load", busy ? "busy" : "idle"},
                        {"round", busy ? r - a.rounds : r},
                        {"seconds", total},
                        {"gain", rep.after.dtExact / rep.before.dtExact},
                        {"load_average", load.empty() ? json(nullptr) : load[0]}};
            if (!a.json)
                std::printf("%-10s %6d %7d %5s %5d %9.3f %8.3f %6.2f\n", c->name, input.elements(), th,
                            busy ? "busy" : "idle", row["round"].get<int>(), total, row["gain"].get<double>(),
                            load.empty() ? -1.0 : load[0].get<double>());
            runs.push_back(row);
        }
    }
    if (a.json) printResult(json{{"rounds", a.rounds}, {"busy_rounds", a.busyRounds}, {"runs", runs}}, machine);
    return 0;
}

int runImproveBench(const ImproveBenchArgs& a) {
    if (a.speed) return runImproveSpeed(a);
    const json machine = machineJson();
    const Material mat;
    const bool quiet = a.json;
    json meshes = json::array(), timing = json::object();
    for (const MeshCase& c : kCases) {
        if (a.tiny && std::string(c.name) != "liver") continue;
        ReadOptions ro;
        ro.scale = c.scale;
        TetMesh mesh = readTetMesh(std::string(CUTSIM_DATA_DIR) + "/" + c.file, ro);
        mesh.source = c.file;  // messages name the data file, not this machine's folders
        const MeshStepStats b = meshStepStats(mesh, mat);
        json row = {{"mesh", c.name},           {"file", c.file},        {"scale", c.scale},
                    {"tets", b.tets},           {"dt_exact", b.dtExact}, {"min_dihedral_deg", b.minDihedralDeg},
                    {"methods", json::object()}};
        json& methods = row["methods"];
        methods["cutsim"] = baseline(mesh, b, mat, [&](const TetMesh& m) {
            TetMesh out = m;
            ImproveOptions o;
            o.material = mat;
            improveMesh(out, o);
            return out;
        });
        methods["tetgen -rO10/7"] =
            baseline(mesh, b, mat, [](const TetMesh& m) { return tetgenOptimize(m, "rO10/7zQ"); });
        // With a quality bound TetGen optimises, but by adding Steiner points.
        methods["tetgen -rqO10/7"] =
            baseline(mesh, b, mat, [](const TetMesh& m) { return tetgenOptimize(m, "rq1.414O10/7zQ"); });
        methods["gmsh"] = baseline(mesh, b, mat, [](const TetMesh& m) {
            return runHelper("cutsim-gmsh-optimize", m, "", "Gmsh's default optimizer");
        });
        methods["gmsh netgen"] = baseline(mesh, b, mat, [](const TetMesh& m) {
            return runHelper("cutsim-gmsh-optimize", m, "Netgen", "Gmsh's Netgen optimizer");
        });
        if (!a.tiny)
            methods["cgal remesh"] = baseline(mesh, b, mat, [](const TetMesh& m) {
                return runHelper("cutsim-cgal-remesh", m, "", "CGAL's make_mesh_3, perturb and exude");
            });
        // Gain against time: no work budget, the wall clock alone.
        TetMesh long_ = mesh;
        ImproveOptions o;
        o.material = mat;
        o.maxEvaluations = LLONG_MAX;
        o.maxSeconds = a.tiny ? 0.5 : a.seconds;
        o.maxRounds = 1 << 20;
        const ImproveReport r = improveMesh(long_, o);
        json hist = json::array();
        for (const auto& p : r.history) hist.push_back({p.seconds, p.dtExact / b.dtExact});
        timing[c.name] = {{"gain_at_0.1s", bestBy(r, 0.1) / b.dtExact},
                          {"gain_at_1s", bestBy(r, 1) / b.dtExact},
                          {"gain_at_10s", bestBy(r, 10) / b.dtExact},
                          {"seconds", r.seconds.back().second},
                          {"history", hist}};
        meshes.push_back(row);
        if (!quiet) std::fprintf(stderr, "  %s done\n", c.name);
    }
    json j = {{"material", {{"E", mat.E}, {"nu", mat.nu}, {"rho", mat.rho}}},
              {"meshes", meshes},
              {"gain_against_time", timing},
              {"liver_sag", liverSag(a.tiny, quiet)},
              {"bar_frequency", barFrequency()}};
    if (!a.plot.empty()) drawPlot(a.plot, timing);
    if (a.json) {
        for (auto& [k, t] : j["gain_against_time"].items()) t.erase("history");
        printResult(j, machine);
        return 0;
    }
    std::printf("exact step after improvement (E %g Pa, nu %g, rho %g); gain = after / before; volume and\n"
                "boundary change relative to the volume and the bounding-box diagonal; seconds on one core\n\n",
                mat.E, mat.nu, mat.rho);
    std::printf("%-10s %-15s %6s %10s %7s %8s %8s %9s %8s\n", "mesh", "method", "tets", "dt [ms]", "gain", "min dih",
                "volume", "boundary", "seconds");
    for (const auto& row : meshes) {
        std::printf("%-10s %-15s %6d %10.4f %7s %8.2f %8s %9s %8s\n", row["mesh"].get<std::string>().c_str(), "input",
                    row["tets"].get<int>(), row["dt_exact"].get<double>() * 1e3, "1",
                    row["min_dihedral_deg"].get<double>(), "", "", "");
        for (const auto& [name, m] : row["methods"].items()) {
            if (m.contains("error")) {
                std::printf("%-10s %-15s failed: %s\n", "", name.c_str(), m["error"].get<std::string>().c_str());
                continue;
            }
            std::printf("%-10s %-15s %6d %10.4f %7.3f %8.2f %+7.2f%% %8.2f%% %8.3f\n", "", name.c_str(),
                        m["tets"].get<int>(), m["dt_exact"].get<double>() * 1e3, m["gain"].get<double>(),
                        m["min_dihedral_deg"].get<double>(), 100 * m["volume_change"].get<double>(),
                        100 * m["boundary_distance_rel"].get<double>(), m["seconds"].get<double>());
        }
    }
    std::printf("\ngain against time (cutsim, wall clock only):\n%-10s %8s %8s %8s\n", "mesh", "0.1 s", "1 s", "10 s");
    for (const auto& [name, t] : timing.items())
        std::printf("%-10s %8.3f %8.3f %8.3f\n", name.c_str(), t["gain_at_0.1s"].get<double>(),
                    t["gain_at_1s"].get<double>(), t["gain_at_10s"].get<double>());
    std::printf("\nliver sag (static error at the input's nodes against the input refined; explicit cost at 0.9 "
                "of the exact step):\n");
    for (const auto& r : j["liver_sag"])
        std::printf("  %-9s %5d tets  dt %.4f ms  error %.4f  wall per simulated second %.3f s\n",
                    r["mesh"].get<std::string>().c_str(), r["tets"].get<int>(), r["dt"].get<double>() * 1e3,
                    r["error"].get<double>(), r["wall_per_sim_second"].get<double>());
    const json& bf = j["bar_frequency"];
    std::printf("\njittered bar (%d tets): first frequency %.5f Hz, improved %.5f Hz (%+.3f%%), regular %.5f Hz; "
                "step gain %.3f\n",
                bf["tets"].get<int>(), bf["f_jittered"].get<double>(), bf["f_improved"].get<double>(),
                100 * bf["frequency_change"].get<double>(), bf["f_regular"].get<double>(), bf["gain"].get<double>());
    if (!a.plot.empty()) std::printf("\nwritten: %s\n", a.plot.c_str());
    return 0;
}

void improveOptions(CLI::App& c, ImproveBenchArgs& a) {
    jsonFlag(c, a.json,
             "{meshes: [{mesh, tets, dt_exact, methods: {name: {dt_exact, gain, tets, volume_change, "
             "boundary_distance_rel, seconds} or {error}}}], gain_against_time, liver_sag, bar_frequency}",
             true);
    tinyFlag(c, a.tiny, "the liver only, short runs");
    c.add_option("--seconds", a.seconds, "Longest run of the gain-against-time table [s]")->capture_default_str();
    plotOption(c, a.plot, "the gain against time");
    c.add_flag("--speed", a.speed,
               "Instead: the improver's seconds at its defaults per mesh and thread count, the runs taking turns, "
               "idle and with another core busy (JSON: {rounds, busy_rounds, runs: [{mesh, tets, threads, load, "
               "round, seconds, gain, load_average}]})");
    c.add_option("--speed-meshes", a.speedMeshes,
                 "--speed: the data meshes to time (liver, liver2, armadillo, "
                 "knight, octopus)")
        ->delimiter(',')
        ->capture_default_str();
    c.add_option("--threads", a.threads, "--speed: the improver's thread counts")
        ->delimiter(',')
        ->check(CLI::Range(1, 1024))
        ->capture_default_str();
    c.add_option("--rounds", a.rounds, "--speed: rounds idle")->check(CLI::Range(1, 1000))->capture_default_str();
    c.add_option("--busy-rounds", a.busyRounds, "--speed: rounds after them with another core busy")
        ->check(CLI::Range(0, 1000))
        ->capture_default_str();
}

}  // namespace

void addImproveBench() {
    addSubcommand("improve",
                  "Mesh improvement: cutsim's improver, TetGen's and Gmsh's optimisers on the data meshes "
                  "(exact step, elements, volume, boundary, seconds), the gain against time, and the liver's "
                  "sag and a bar's frequency before and after",
                  improveOptions, runImproveBench);
}

}  // namespace cutsim::bench
