// A run's output folder, written whole or not at all: everything goes into a staging folder beside
// it, which replaces the folder at the end (commit) or, when the run is stopped, is kept as
// FOLDER.incomplete; neither a crash nor a signal leaves half a run under FOLDER.
#pragma once

#include <csignal>
#include <filesystem>
#include <string>

namespace cutsim::app {

class StagedFolder {
public:
    // InputError when `out` names no folder, is a file, or is a folder holding files that are not
    // a cutsim run's (an existing run's folder, with report.json, is replaced; an empty one too).
    explicit StagedFolder(const std::string& out);
    ~StagedFolder();  // neither committed nor kept: the staging folder is removed
    StagedFolder(const StagedFolder&) = delete;
    StagedFolder& operator=(const StagedFolder&) = delete;

    const std::filesystem::path& staging() const { return staging_; }
    const std::filesystem::path& target() const { return target_; }
    std::filesystem::path incomplete() const { return target_.string() + ".incomplete"; }

    void commit();          // the staging folder becomes `out`, replacing what was there
    void keepIncomplete();  // the staging folder becomes `out`.incomplete; `out` is left as it was

private:
    std::filesystem::path target_, staging_;
    bool done_ = false;
};

// SIGINT and SIGTERM set a flag instead of killing the process while this lives, so a run can stop
// between steps and leave its outputs whole; the previous handlers come back afterwards.
class InterruptGuard {
public:
    InterruptGuard();
    ~InterruptGuard();
    InterruptGuard(const InterruptGuard&) = delete;
    InterruptGuard& operator=(const InterruptGuard&) = delete;
    int signal() const;  // the signal caught, 0 for none

private:
    struct sigaction oldInt_ {
    }, oldTerm_{};
};

}  // namespace cutsim::app
