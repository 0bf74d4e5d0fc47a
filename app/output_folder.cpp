#include "output_folder.hpp"

#include "util/input_error.hpp"

#include <unistd.h>

namespace cutsim::app {

namespace fs = std::filesystem;

namespace {

volatile std::sig_atomic_t g_signal = 0;

extern "C" void onSignal(int sig) { g_signal = sig; }

// A folder a run may replace: empty, or holding a report.json (an earlier run's).
bool replaceable(const fs::path& dir) {
    std::error_code ec;
    return fs::is_empty(dir, ec) || fs::exists(dir / "report.json", ec);
}

}  // namespace

StagedFolder::StagedFolder(const std::string& out) {
    const fs::path abs = fs::absolute(fs::path(out)).lexically_normal();
    target_ = abs.has_filename() ? abs : abs.parent_path();
    const std::string name = target_.filename().string();
    if (name.empty() || name == "." || name == ".." || target_ == target_.root_path())
        throw InputError(out, 0, "--out must name a folder to create or replace");
    std::error_code ec;
    if (fs::exists(target_, ec) && !fs::is_directory(target_, ec))
        throw InputError(out, 0, "--out exists and is not a folder");
    if (fs::is_directory(target_, ec) && !replaceable(target_))
        throw InputError(out, 0,
                         "--out is a folder with files that are not a cutsim run's (no report.json); a run replaces "
                         "its folder whole, so give a new, empty or earlier run's folder");
    const fs::path parent = target_.parent_path();
    fs::create_directories(parent, ec);
    // stagings left by a killed run into the same folder
    std::string prefix = ".";
    prefix += name;
    prefix += ".staging-";
    for (const auto& e : fs::directory_iterator(parent, ec))
        if (e.path().filename().string().rfind(prefix, 0) == 0) fs::remove_all(e.path(), ec);
    staging_ = parent / (prefix + std::to_string(::getpid()));
    ec.clear();
    fs::create_directories(staging_, ec);
    if (ec) throw InputError(out, 0, "cannot create the output folder (" + ec.message() + ")");
}

StagedFolder::~StagedFolder() {
    if (done_) return;
    std::error_code ec;
    fs::remove_all(staging_, ec);
}

void StagedFolder::commit() {
    std::error_code ec;
    std::string oldName = ".";  // built in steps: GCC 12 warns falsely (-Wrestrict) on "." + std::string
    oldName += target_.filename().string();
    oldName += ".old-" + std::to_string(::getpid());
    const fs::path old = target_.parent_path() / oldName;
    const bool had = fs::exists(target_, ec);
    if (had) {
        fs::rename(target_, old, ec);
        if (ec) throw InputError(target_.string(), 0, "cannot replace the output folder (" + ec.message() + ")");
    }
    fs::rename(staging_, target_, ec);
    if (ec) {
        if (had) fs::rename(old, target_, ec);
        throw InputError(target_.string(), 0, "cannot move the run's outputs into place (" + ec.message() + ")");
    }
    done_ = true;
    if (had) fs::remove_all(old, ec);
}

void StagedFolder::keepIncomplete() {
    std::error_code ec;
    fs::remove_all(incomplete(), ec);
    fs::rename(staging_, incomplete(), ec);
    done_ = !ec;
}

InterruptGuard::InterruptGuard() {
    g_signal = 0;
    struct sigaction sa {};
    sa.sa_handler = onSignal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, &oldInt_);
    sigaction(SIGTERM, &sa, &oldTerm_);
}

InterruptGuard::~InterruptGuard() {
    sigaction(SIGINT, &oldInt_, nullptr);
    sigaction(SIGTERM, &oldTerm_, nullptr);
}

int InterruptGuard::signal() const { return g_signal; }

}  // namespace cutsim::app
