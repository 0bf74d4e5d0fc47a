#include "commands.hpp"
#include "run.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>

namespace cutsim::app {

void addRunCommand(CLI::App& app) {
    auto* cmd = app.add_subcommand("run", "Run a scene: frames, video, report.json and final.vtu in --out");
    static std::string scene;
    static RunOptions opt;
    static std::vector<std::string> sets;
    static bool noRender = false;
    cmd->add_option("scene", scene, "Scene file (JSON, see docs/scene-format.md)")->required();
    cmd->add_option("--out", opt.out, "Output folder")->required();
    cmd->add_flag("--no-render", noRender, "No frames and no GL context");
    cmd->add_option("--threads", opt.threads,
                    "Worker threads (0: chosen by measuring one thread against all cores as the run goes)")
        ->check(CLI::Range(0, 1024));
    cmd->add_option("--set", sets, "Override a scene value: key.path=value (JSON value)");
    cmd->add_flag("--quiet", opt.quiet, "No progress output");
    cmd->callback([] {
        try {
            opt.render = !noRender;
            const SceneDef def = loadScene(scene, sets);
            setExitCode(runScene(def, opt));
        } catch (const std::exception& e) {
            std::fprintf(stderr, "error: %s\n", e.what());
            setExitCode(2);
        }
    });
}

}  // namespace cutsim::app
