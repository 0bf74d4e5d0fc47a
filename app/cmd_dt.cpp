// `cutsim dt`: the stable time step of a mesh, exact, certified and per-element estimates
// (docs/method.md sec. 2-3, thesis ch. 4), with the shape measures' correlation to R1R.
#include "commands.hpp"
#include "util/stopwatch.hpp"

#include "fem/model.hpp"
#include "mesh/io.hpp"
#include "timestep/analyzer.hpp"
#include "timestep/quality.hpp"
#include "timestep/timestep.hpp"
#include "util/json_text.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>
#include <numeric>

namespace cutsim::app {
namespace {

struct DtArgs {
    std::string mesh;
    std::string vtu;
    double scale = 1.0;
    Material material;
    bool json = false;
    int worst = 10;
    bool reorient = false;
};

double minOf(const Eigen::VectorXd& v) { return v.size() ? v.minCoeff() : std::numeric_limits<double>::infinity(); }

int runDt(const DtArgs& a) {
    try {
        if (!a.material.valid())
            throw InputError("material: need E > 0, -1 < nu < 0.5, rho > 0 (got E=" + std::to_string(a.material.E) +
                             ", nu=" + std::to_string(a.material.nu) + ", rho=" + std::to_string(a.material.rho) + ")");
        ReadOptions opts;
        opts.scale = a.scale;
        opts.reorient = a.reorient;
        const TetMesh mesh = readTetMesh(a.mesh, opts);
        const Model m = buildModel(mesh, a.material);

        // Stages share the assembled rows of K; each is timed on its own.
        auto t0 = WallClock::now();
        const StiffnessRows rows = assembleStiffnessRows(m);
        const double tRows = secondsSince(t0);
        t0 = WallClock::now();
        const double dtCert = certifiedDt(m, rows);
        const double tCert = secondsSince(t0);
        t0 = WallClock::now();
        ElementEstimates est;
        estimateElements(m, rows, assembleStiffnessDiagonal(m), nullptr, est);
        const double tEst = secondsSince(t0);
        t0 = WallClock::now();
        const ShapeMeasures shapes = shapeMeasures(m);
        const double tShapes = secondsSince(t0);
        t0 = WallClock::now();
        const ExactResult ex = exactCriticalDt(m, rows);
        const double tExact = secondsSince(t0);

        // Worst elements by R1R.
        std::vector<int> order(m.elements());
        std::iota(order.begin(), order.end(), 0);
        const int nWorst = std::clamp(a.worst, 0, m.elements());
        std::partial_sort(order.begin(), order.begin() + nWorst, order.end(),
                          [&](int x, int y) { return est.r1r(x) < est.r1r(y); });

        nlohmann::json j;
        j["file"] = a.mesh;
        j["nodes"] = m.nodes();
        j["tets"] = m.elements();
        j["material"] = {{"E", a.material.E}, {"nu", a.material.nu}, {"rho", a.material.rho}};
        j["dt_exact"] = ex.dt;
        j["dt_certified"] = dtCert;
        j["dt_r1r"] = minOf(est.r1r);
        j["dt_hs"] = minOf(est.hs);
        j["dt_hp"] = minOf(est.hp);
        j["dt_le"] = minOf(est.le);
        j["dt_element"] = minOf(est.element);
        j["lambda_max"] = ex.lambdaMax;
        j["exact_matvecs"] = ex.matvecs;
        nlohmann::json corr = nlohmann::json::object();
        const auto correlations = correlationsWithR1R(est, shapes);
        for (const auto& [name, r] : correlations) corr[name] = r;
        j["correlation"] = corr;
        nlohmann::json worst = nlohmann::json::array();
        for (int k = 0; k < nWorst; ++k) {
            const int e = order[k];
            worst.push_back({{"element", e},
                             {"r1r", est.r1r(e)},
                             {"hs", est.hs(e)},
                             {"hp", est.hp(e)},
                             {"le", est.le(e)},
                             {"element_eigenvalue", est.element(e)}});
        }
        j["worst"] = worst;
        j["seconds"] = {
            {"rows", tRows}, {"exact", tExact}, {"certified", tCert}, {"estimators", tEst}, {"shapes", tShapes}};

        if (!a.vtu.empty()) {
            // Per-element fields [s]; critical marks R1R dt < 1.1 dt_exact (the hybrid's threshold, sec. 5).
            auto field = [](const char* name, const Eigen::VectorXd& v) {
                return Field{name, std::vector<double>(v.data(), v.data() + v.size())};
            };
            Field critical{"critical", std::vector<double>(m.elements())};
            for (int e = 0; e < m.elements(); ++e) critical.values[e] = est.r1r(e) < 1.1 * ex.dt ? 1.0 : 0.0;
            writeVtu(a.vtu, mesh,
                     {field("dt_r1r", est.r1r), field("dt_hs", est.hs), field("dt_hp", est.hp), field("dt_le", est.le),
                      field("dt_element", est.element), critical, field("mean_ratio", shapes.meanRatio)});
            j["written"] = a.vtu;
        }

        if (a.json) {
            std::cout << jsonText(j);
            return 0;
        }
        auto row = [&](const char* name, double dt, double seconds) {
            std::printf("  %-22s %10.4f ms %8.3f", name, dt * 1e3, dt / ex.dt);
            if (seconds >= 0) std::printf(" %9.4f s", seconds);
            std::printf("\n");
        };
        std::printf("mesh:      %s\n", a.mesh.c_str());
        std::printf("nodes:     %d\ntets:      %d\n", m.nodes(), m.elements());
        std::printf("material:  E = %g Pa, nu = %g, rho = %g kg/m^3 (c_p = %.4g m/s)\n\n", a.material.E, a.material.nu,
                    a.material.rho, a.material.pWaveSpeed());
        std::printf("  %-22s %13s %8s %11s\n", "time step", "min dt", "/ exact", "time");
        row("exact (Lanczos)", ex.dt, tExact + tRows);
        row("certified (Gershgorin)", dtCert, tCert + tRows);
        row("R1R", minOf(est.r1r), tEst + tRows);
        row("Hs", minOf(est.hs), -1);
        row("Hp", minOf(est.hp), -1);
        row("Le / c_p", minOf(est.le), -1);
        row("element eigenvalue", minOf(est.element), -1);
        std::printf("  (stiffness rows %.4f s, shared; estimators together %.4f s)\n\n", tRows, tEst);
        std::printf("correlation with the R1R dt across elements (Pearson r):\n");
        for (const auto& [name, r] : correlations) std::printf("  %-24s %7.3f\n", name.c_str(), r);
        if (nWorst > 0) {
            std::printf("\n%d worst elements by R1R (ms):\n  %8s %9s %9s %9s %9s %9s\n", nWorst, "element", "R1R", "Hs",
                        "Hp", "Le", "element");
            for (int k = 0; k < nWorst; ++k) {
                const int e = order[k];
                std::printf("  %8d %9.4f %9.4f %9.4f %9.4f %9.4f\n", e, est.r1r(e) * 1e3, est.hs(e) * 1e3,
                            est.hp(e) * 1e3, est.le(e) * 1e3, est.element(e) * 1e3);
            }
        }
        if (!a.vtu.empty()) std::printf("\nwritten:   %s\n", a.vtu.c_str());
        return 0;
    } catch (const InputError& e) {
        std::cerr << "error: " << e.what() << "\n";
        return 2;
    } catch (const EigenSolveError& e) {
        std::cerr << "error: " << e.what() << "\n";
        return 1;
    }
}

}  // namespace

void addDtCommand(CLI::App& app) {
    auto args = std::make_shared<DtArgs>();
    CLI::App* cmd = app.add_subcommand(
        "dt", "Stable time step of a tet mesh: exact (Lanczos), certified lower bound (Gershgorin) and the "
              "per-element estimators R1R, Hs, Hp, Le, element eigenvalue (thesis ch. 4)");
    cmd->add_option("MESH", args->mesh, "Tet mesh file (.msh, .node/.ele, .mesh, .vtu)")->required();
    cmd->add_option("--scale", args->scale, "Multiply every coordinate by S to get meters")->check(CLI::PositiveNumber);
    cmd->add_option("--E", args->material.E, "Young's modulus [Pa]")->capture_default_str();
    cmd->add_option("--nu", args->material.nu, "Poisson's ratio [-]")->capture_default_str();
    cmd->add_option("--rho", args->material.rho, "Density [kg/m^3]")->capture_default_str();
    cmd->add_flag("--json", args->json,
                  "Print one JSON object: nodes, tets, dt_exact, dt_certified, dt_r1r, dt_hs, dt_hp, dt_le, dt_element "
                  "(minimum over elements) [s], correlation {measure: r}, worst [...], seconds {...}");
    cmd->add_option("--worst", args->worst, "List the N elements with the smallest R1R dt")->capture_default_str();
    cmd->add_option("--vtu", args->vtu,
                    "Write per-element fields (each estimate [s], critical = R1R dt < 1.1 exact dt) to OUT.vtu");
    cmd->add_flag("--reorient", args->reorient, "Fix inverted tets by swapping two nodes instead of rejecting them");
    cmd->callback([args] { setExitCode(runDt(*args)); });
}

}  // namespace cutsim::app
