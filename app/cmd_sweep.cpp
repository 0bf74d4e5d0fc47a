// `cutsim sweep`: the product of --set value lists as jobs of `cutsim run`, each in a folder named
// by a hash of its scene; run here on the local cores, through GNU parallel, or written as a Slurm
// job array; then one summary.csv of every job's report (docs/commands.md).
#include "commands.hpp"

#include "sim/scene.hpp"
#include "util/atomic_file.hpp"
#include "util/json_text.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

extern char** environ;

namespace cutsim::app {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct SweepArgs {
    std::string scene, out, engine = "local";
    std::vector<std::string> sets;
    int seeds = 1, jobs = 0, threads = 1;
    bool render = false, noRun = false;
};

struct Axis {
    std::string key;
    std::vector<std::string> values;
};

struct Job {
    std::vector<std::string> sets;    // key=value, one per axis
    std::vector<std::string> values;  // the axes' values, for the summary
    int seed = 0;
    std::string hash;
    fs::path dir;                                 // job.json, log.txt and the run's folder
    fs::path run() const { return dir / "run"; }  // the run replaces its folder whole (cutsim run)
    std::vector<std::string> argv;                // the `cutsim run` command
};

// key=a,b,c: values split at the commas outside brackets and quotes, so that a JSON array is one value.
Axis parseAxis(const std::string& arg) {
    const auto eq = arg.find('=');
    if (eq == std::string::npos || eq == 0) throw InputError("--set " + arg + ": expected key.path=a,b,c");
    Axis a{arg.substr(0, eq), {}};
    std::string cur;
    int depth = 0;
    bool quoted = false;
    for (const char c : arg.substr(eq + 1)) {
        if (c == '"') quoted = !quoted;
        if (!quoted && (c == '[' || c == '{')) ++depth;
        if (!quoted && (c == ']' || c == '}')) --depth;
        if (c == ',' && depth == 0 && !quoted) {
            a.values.push_back(cur);
            cur.clear();
        } else {
            cur += c;
        }
    }
    a.values.push_back(cur);
    for (const auto& v : a.values)
        if (v.empty()) throw InputError("--set " + arg + ": an empty value");
    return a;
}

std::string fnv1a(const std::string& s) {
    std::uint64_t h = 1469598103934665603ull;
    for (const unsigned char c : s) h = (h ^ c) * 1099511628211ull;
    char buf[20];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
    return buf;
}

// A word for /bin/sh: single-quoted unless it needs no quotes.
std::string shellQuote(const std::string& s) {
    if (!s.empty() && s.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-+=./:,@") ==
                          std::string::npos)
        return s;
    std::string q = "'";
    for (const char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}

std::string commandLine(const Job& j) {
    std::string cmd;
    for (const auto& a : j.argv) cmd += (cmd.empty() ? "" : " ") + shellQuote(a);
    return cmd + " > " + shellQuote((j.dir / "log.txt").string()) + " 2>&1";
}

bool done(const Job& j) { return fs::exists(j.run() / "report.json"); }

std::string selfPath() {
    std::error_code ec;
    const fs::path p = fs::read_symlink("/proc/self/exe", ec);
    return ec ? std::string("cutsim") : p.string();
}

// Runs argv with stdout and stderr into log; returns the pid.
pid_t spawn(const std::vector<std::string>& argv, const std::string& log) {
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&fa, 1, 2);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    pid_t pid = 0;
    const int rc = posix_spawnp(&pid, args[0], &fa, nullptr, args.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) throw std::runtime_error("cannot start " + argv[0] + ": " + std::strerror(rc));
    return pid;
}

// At most `slots` jobs at once on this machine.
void runLocal(const std::vector<const Job*>& todo, int slots) {
    std::map<pid_t, const Job*> running;
    size_t next = 0;
    while (next < todo.size() || !running.empty()) {
        while (next < todo.size() && static_cast<int>(running.size()) < slots) {
            const Job* j = todo[next++];
            running[spawn(j->argv, (j->dir / "log.txt").string())] = j;
        }
        int status = 0;
        const pid_t pid = waitpid(-1, &status, 0);
        if (pid < 0) break;
        running.erase(pid);
    }
}

std::string csvField(const std::string& s) {
    if (s.find_first_of(",\"\n") == std::string::npos) return s;
    std::string q = "\"";
    for (const char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
}

std::string num(double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%.17g", v);
    return b;
}

// One row a job: its values, then the key figures of its report.json (status "missing": no report).
std::string summary(const std::vector<Axis>& axes, const std::vector<Job>& jobs, int& failed) {
    std::ostringstream os;
    os << "job,seed";
    for (const auto& a : axes) os << ',' << csvField(a.key);
    os << ",status,steps,dt,cuts,cut_steps,tool_force,state_hash,wall_time\n";
    failed = 0;
    for (const Job& j : jobs) {
        os << j.hash << ',' << j.seed;
        for (const auto& v : j.values) os << ',' << csvField(v);
        std::ifstream in(j.run() / "report.json");
        json r;
        try {
            if (in) r = json::parse(in);
        } catch (const json::exception&) {
            r = nullptr;
        }
        if (!r.is_object()) {
            os << ",missing,,,,,,,\n";
            ++failed;
            continue;
        }
        const std::string status = r.value("status", "missing");
        failed += status != "ok";
        const double force = r.contains("tool") ? r["tool"].value("max_force", 0.0) : 0.0;
        const long cutSteps = r.contains("blade") ? r["blade"].value("cut_steps", 0L) : 0L;
        const size_t cuts = r.contains("cuts") && r["cuts"].is_array() ? r["cuts"].size() : 0;
        os << ',' << csvField(status) << ',' << r.value("steps", 0L) << ',' << num(r.value("dt", 0.0)) << ',' << cuts
           << ',' << cutSteps << ',' << num(force) << ',' << r.value("state_hash", "") << ','
           << num(r.value("wall_time", 0.0)) << '\n';
    }
    return os.str();
}

// Slurm: one array task per line of jobs.txt.
std::string slurmScript(const fs::path& list, size_t n) {
    std::ostringstream s;
    s << "#!/bin/bash\n"
      << "# cutsim sweep: one array task a job; submit with sbatch, then run the same `cutsim sweep` again\n"
      << "# (every job done, nothing runs) for summary.csv.\n"
      << "#SBATCH --job-name=cutsim-sweep\n"
      << "#SBATCH --array=1-" << n << "\n"
      << "#SBATCH --cpus-per-task=1\n"
      << "#SBATCH --output=/dev/null\n"
      << "set -euo pipefail\n"
      << "eval \"$(sed -n \"${SLURM_ARRAY_TASK_ID}p\" " << shellQuote(list.string()) << ")\"\n";
    return s.str();
}

int runSweep(const SweepArgs& a) {
    if (a.sets.empty()) throw InputError("sweep: give at least one --set key=a,b,c");
    std::vector<Axis> axes;
    for (const auto& s : a.sets) axes.push_back(parseAxis(s));
    const fs::path out = fs::absolute(a.out);
    const std::string scene = fs::absolute(a.scene).lexically_normal().string(), self = selfPath();

    // The product of the axes, the first varying slowest; every job's scene is checked before anything runs.
    std::vector<Job> jobs;
    std::vector<size_t> idx(axes.size(), 0);
    while (true) {
        for (int seed = 0; seed < a.seeds; ++seed) {
            Job j;
            j.seed = seed;
            for (size_t k = 0; k < axes.size(); ++k) {
                j.values.push_back(axes[k].values[idx[k]]);
                j.sets.push_back(axes[k].key + "=" + axes[k].values[idx[k]]);
            }
            const SceneDef def = loadScene(scene, j.sets);
            j.hash = fnv1a(def.source.dump() + (a.seeds > 1 ? "\nseed " + std::to_string(seed) : ""));
            j.dir = out / j.hash;
            j.argv = {self, "run", scene, "--out", j.run().string(), "--quiet", "--threads", std::to_string(a.threads)};
            if (!a.render) j.argv.push_back("--no-render");
            for (const auto& s : j.sets) j.argv.insert(j.argv.end(), {"--set", s});
            jobs.push_back(std::move(j));
        }
        size_t k = axes.size();
        while (k > 0 && ++idx[k - 1] == axes[k - 1].values.size()) idx[--k] = 0;
        if (k == 0) break;
    }

    std::error_code ec;
    fs::create_directories(out, ec);
    if (ec) throw InputError(a.out, 0, "cannot create the output folder: " + ec.message());
    std::vector<const Job*> todo;
    for (const Job& j : jobs) {
        fs::create_directories(j.dir, ec);
        if (ec) throw InputError(j.dir.string(), 0, "cannot create the job folder: " + ec.message());
        json info = {{"scene", scene}, {"set", j.sets}, {"seed", j.seed}};
        writeFileAtomic((j.dir / "job.json").string(), jsonText(info));
        if (!done(j)) todo.push_back(&j);
    }
    const int slots = a.jobs > 0 ? a.jobs : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
    std::fprintf(stderr, "sweep: %zu jobs, %zu done, %zu to run (%s)\n", jobs.size(), jobs.size() - todo.size(),
                 todo.size(), a.engine.c_str());

    if (!todo.empty()) {
        std::string list;
        for (const Job* j : todo) list += commandLine(*j) + "\n";
        const fs::path listPath = out / "jobs.txt";
        writeFileAtomic(listPath.string(), list);
        if (a.engine == "slurm") {
            const fs::path script = out / "sweep.sbatch";
            writeFileAtomic(script.string(), slurmScript(listPath, todo.size()));
            std::fprintf(stderr,
                         "sweep: submit with `sbatch %s`; when the array is done, run this sweep again for %s\n",
                         script.c_str(), (out / "summary.csv").c_str());
            return 0;
        }
        if (a.noRun) {
            std::fprintf(stderr, "sweep: job list %s (not run)\n", listPath.c_str());
            return 0;
        }
        if (a.engine == "parallel") {
            const std::vector<std::string> cmd = {"parallel",   "--will-cite",    "--jobs", std::to_string(slots),
                                                  "--arg-file", listPath.string()};
            const pid_t pid = spawn(cmd, (out / "parallel.log").string());
            int status = 0;
            waitpid(pid, &status, 0);
            if (WIFEXITED(status) && WEXITSTATUS(status) == 127)
                throw std::runtime_error("GNU parallel is not installed (apt-get install parallel); the job list is " +
                                         listPath.string());
        } else {
            runLocal(todo, slots);
        }
    }
    int failed = 0;
    writeFileAtomic((out / "summary.csv").string(), summary(axes, jobs, failed));
    std::fprintf(stderr, "sweep: %zu jobs, %d not ok -> %s\n", jobs.size(), failed, (out / "summary.csv").c_str());
    return failed ? 1 : 0;
}

}  // namespace

void addSweepCommand(CLI::App& app) {
    auto* cmd = app.add_subcommand("sweep", "Run a scene over the product of --set value lists; summary.csv in --out");
    static SweepArgs a;
    cmd->add_option("scene", a.scene, "Scene file (JSON, see docs/scene-format.md)")->required();
    cmd->add_option("--set", a.sets, "key.path=a,b,c: the values of one axis (JSON values; commas inside [] stay)")
        ->required();
    cmd->add_option("--out", a.out, "Output folder: one folder a job, jobs.txt, summary.csv")->required();
    cmd->add_option("--seeds", a.seeds, "Repeats of every combination, each its own job (seed 0..N-1)")
        ->check(CLI::Range(1, 100000));
    cmd->add_option("--jobs", a.jobs, "Jobs at once (0: one a core)")->check(CLI::Range(0, 4096));
    cmd->add_option("--threads", a.threads, "Threads of each job (cutsim run --threads; 0: chosen by measuring)")
        ->check(CLI::Range(0, 1024));
    cmd->add_option("--engine", a.engine,
                    "local: run here; parallel: GNU parallel on jobs.txt; slurm: write a job array")
        ->check(CLI::IsMember({"local", "parallel", "slurm"}));
    cmd->add_flag("--render", a.render, "Let the jobs render frames (off by default)");
    cmd->add_flag("--no-run", a.noRun, "Only write jobs.txt (and job.json in each folder)");
    cmd->callback([] {
        try {
            setExitCode(runSweep(a));
        } catch (const std::exception& e) {
            std::fprintf(stderr, "error: %s\n", e.what());
            setExitCode(2);
        }
    });
}

}  // namespace cutsim::app
