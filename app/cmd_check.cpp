// `cutsim check SCENE --golden DIR`: screenshot tests. Runs the scene offscreen as `cutsim run`
// does and compares chosen frames with the PNGs in DIR by the renderdiff rule (image_diff.hpp);
// --update writes them. DIR/golden.json names the renderer that made them, so frames from another
// GL driver are reported as such rather than as a regression.
#include "commands.hpp"
#include "run.hpp"
#include "sim/simulation.hpp"
#include "util/atomic_file.hpp"
#include "util/stopwatch.hpp"

#ifdef CUTSIM_HAVE_RENDER
#include "image_diff.hpp"
#include "png_writer.hpp"
#include "util/json_text.hpp"
#endif

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

namespace cutsim::app {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct CheckArgs {
    std::string scene, golden, out = "check_out", frames, junit;
    std::vector<std::string> sets;
    int tolerance = 5;
    double maxFailing = 0.001;
    bool update = false;
    int threads = 0;
    CLI::Option* toleranceOpt = nullptr;
    CLI::Option* maxFailingOpt = nullptr;
};

// "0,15,last" -> {0, 15, -1}
std::vector<int> parseFrames(const std::string& s) {
    std::vector<int> out;
    std::stringstream in(s);
    for (std::string item; std::getline(in, item, ',');) {
        if (item == "last") {
            out.push_back(-1);
            continue;
        }
        char* end = nullptr;
        const long v = std::strtol(item.c_str(), &end, 10);
        if (item.empty() || *end || v < 0 || v >= 100000000)
            throw InputError("--frames: expected frame numbers >= 0 or \"last\" separated by commas, got \"" + s +
                             "\"");
        out.push_back(static_cast<int>(v));
    }
    if (out.empty()) throw InputError("--frames: no frames given");
    return out;
}

std::string frameName(int f) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06d", f);
    return name;
}

std::string readBytes(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    if (!in) throw InputError(p.string() + ": cannot read");
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string xmlEscape(const std::string& s) {
    std::string o;
    for (char c : s) {
        switch (c) {
        case '&': o += "&amp;"; break;
        case '<': o += "&lt;"; break;
        case '>': o += "&gt;"; break;
        case '"': o += "&quot;"; break;
        default: o += c;
        }
    }
    return o;
}

std::string rendererText(const json& r) {
    if (!r.is_object()) return "unknown";
    return r.value("vendor", "?") + " / " + r.value("renderer", "?") + " / " + r.value("version", "?");
}

#ifdef CUTSIM_HAVE_RENDER
struct FrameResult {
    int frame = 0;
    bool pass = false;
    std::string line;  // what the frame's line says after "frame N: "
};

// golden.json of a golden folder, its frame list checked.
json readGoldenMeta(const CheckArgs& a) {
    const fs::path mp = fs::path(a.golden) / "golden.json";
    if (!fs::exists(mp))
        throw InputError(mp.string() + ": no golden images here (make them with cutsim check " + a.scene +
                         " --golden " + a.golden + " --update)");
    json meta;
    try {
        meta = json::parse(readBytes(mp));
    } catch (const json::parse_error& e) {
        throw InputError(mp.string() + ": invalid JSON: " + e.what());
    }
    bool ok = meta.is_object() && meta.contains("frames") && meta["frames"].is_array();
    for (size_t i = 0; ok && i < meta["frames"].size(); ++i)
        ok = meta["frames"][i].is_number_integer() && meta["frames"][i].get<long>() >= 0;
    if (!ok) throw InputError(mp.string() + ": frames: must be an array of frame numbers >= 0");
    return meta;
}

// The frames to compare, of a run with `frames` frames: all when none were asked for, -1 the
// last; sorted, each once.
std::vector<int> framesOfRun(std::vector<int> wanted, int frames) {
    if (wanted.empty())
        for (int f = 0; f < frames; ++f) wanted.push_back(f);
    for (int& f : wanted) {
        if (f < 0) f = frames - 1;
        if (f >= frames)
            throw InputError("frame " + std::to_string(f) + " asked for, but the run has " + std::to_string(frames) +
                             " frames (0 to " + std::to_string(frames - 1) + ")");
    }
    std::sort(wanted.begin(), wanted.end());
    wanted.erase(std::unique(wanted.begin(), wanted.end()), wanted.end());
    return wanted;
}

int writeGoldens(const CheckArgs& a, const SceneDef& sc, const std::vector<int>& wanted, const json& renderer) {
    const fs::path golden(a.golden), out(a.out);
    fs::create_directories(golden);
    for (int f : wanted) {
        const std::string name = frameName(f) + ".png";
        writeFileAtomic((golden / name).string(), readBytes(out / "frames" / name));
        std::printf("frame %d: written %s\n", f, (golden / name).string().c_str());
    }
    const json m = {{"scene", sc.name},
                    {"frames", wanted},
                    {"width", sc.capture.width},
                    {"height", sc.capture.height},
                    {"renderer", renderer}};
    writeFileAtomic((golden / "golden.json").string(), jsonText(m));
    std::printf("%s: %zu golden frames in %s (renderer %s)\n", sc.name.c_str(), wanted.size(), a.golden.c_str(),
                rendererText(renderer).c_str());
    return 0;
}

// Frame f of the run against its golden; a failing one leaves its diff and a side-by-side.
FrameResult compareFrame(const CheckArgs& a, int f, int tol, double maxFailing, double& compareSeconds) {
    const fs::path golden(a.golden), out(a.out);
    FrameResult r;
    r.frame = f;
    const std::string name = frameName(f);
    const fs::path ref = golden / (name + ".png");
    if (!fs::exists(ref)) {
        r.line = "FAIL: no golden image " + ref.string();
        return r;
    }
    const render::Image want = render::readPng(ref.string());
    const render::Image got = render::readPng((out / "frames" / (name + ".png")).string());
    const Stopwatch sw;
    render::ImageDiff d = render::diffImages(want, got, tol, false);
    compareSeconds += sw.seconds();
    char line[512];
    if (!d.sameSize) {
        std::snprintf(line, sizeof line, "FAIL: size %dx%d, golden %dx%d", got.width, got.height, want.width,
                      want.height);
        r.line = line;
        return r;
    }
    r.pass = d.fraction <= maxFailing;
    std::snprintf(line, sizeof line, "%s: %.4f%% of pixels differ by more than %d (allowed %.4f%%), max %d",
                  r.pass ? "pass" : "FAIL", 100 * d.fraction, tol, 100 * maxFailing, d.maxChannel);
    r.line = line;
    if (!r.pass) {
        d = render::diffImages(want, got, tol, true);
        const fs::path diff = out / (name + ".diff.png"), side = out / (name + ".side.png");
        render::writePng(diff.string(), d.diff);
        render::writePng(side.string(), render::sideBySide(want, got, d.diff));
        r.line += "; diff " + diff.string() + ", golden | run | diff " + side.string();
    }
    return r;
}

void writeJunit(const std::string& path, const SceneDef& sc, const std::vector<FrameResult>& results, int failed,
                const json& renderer, const json& goldenRenderer) {
    std::string x = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
    x += "<testsuites tests=\"" + std::to_string(results.size()) + "\" failures=\"" + std::to_string(failed) + "\">\n";
    x += "  <testsuite name=\"" + xmlEscape("cutsim check " + sc.name) + "\" tests=\"" +
         std::to_string(results.size()) + "\" failures=\"" + std::to_string(failed) + "\">\n";
    x += "    <properties><property name=\"renderer\" value=\"" + xmlEscape(rendererText(renderer)) +
         "\"/><property name=\"golden_renderer\" value=\"" + xmlEscape(rendererText(goldenRenderer)) +
         "\"/></properties>\n";
    for (const FrameResult& r : results) {
        x += "    <testcase classname=\"" + xmlEscape(sc.name) + "\" name=\"" + frameName(r.frame) + "\"";
        if (r.pass)
            x += "/>\n";
        else
            x += "><failure message=\"" + xmlEscape(r.line) + "\"/></testcase>\n";
    }
    x += "  </testsuite>\n</testsuites>\n";
    writeFileAtomic(path, x);
}

int runCheck(const CheckArgs& a) {
    SceneDef sc = loadScene(a.scene, a.sets);
    // Every frame as a PNG, no video and no mesh: only the frames are compared.
    sc.capture.enabled = true;
    sc.capture.video = false;
    sc.capture.pngEvery = 1;
    sc.writeVtu = false;
    const CheckSettings& fromScene = sc.capture.check;
    const int tol = a.toleranceOpt->count() ? a.tolerance : fromScene.maxDiff;
    const double maxFailing = a.maxFailingOpt->count() ? a.maxFailing : fromScene.maxFailing;

    const json meta = a.update ? json() : readGoldenMeta(a);
    std::vector<int> wanted = !a.frames.empty()           ? parseFrames(a.frames)
                              : !fromScene.frames.empty() ? fromScene.frames
                                                          : std::vector<int>{};
    if (wanted.empty() && !a.update)
        for (const json& f : meta["frames"]) wanted.push_back(f.get<int>());

    RunOptions ro;
    ro.out = a.out;
    ro.threads = a.threads;
    ro.quiet = true;
    // the run replaces `out` whole (output_folder.hpp): no frame or diff of an earlier check stays
    const int code = runScene(sc, ro);
    const json report = json::parse(readBytes(fs::path(a.out) / "report.json"));
    if (code != 0) {
        std::fprintf(stderr, "error: %s: the run did not finish (%s); nothing compared\n", a.scene.c_str(),
                     report.value("status", "?").c_str());
        return code;
    }
    const int frames = report.value("frames", 0);
    if (frames == 0) throw InputError(a.scene + ": no frames were rendered (see the message above)");
    wanted = framesOfRun(std::move(wanted), frames);
    const json renderer = report.value("renderer", json());
    if (a.update) return writeGoldens(a, sc, wanted, renderer);

    const json goldenRenderer = meta.value("renderer", json());
    const bool otherRenderer = goldenRenderer != renderer;
    if (otherRenderer)
        std::printf("note: the goldens were made with renderer %s; this run uses %s\n",
                    rendererText(goldenRenderer).c_str(), rendererText(renderer).c_str());
    std::vector<FrameResult> results;
    double compareSeconds = 0;
    int failed = 0;
    for (int f : wanted) {
        results.push_back(compareFrame(a, f, tol, maxFailing, compareSeconds));
        if (!results.back().pass && otherRenderer) results.back().line += " (goldens from another renderer)";
    }
    for (const FrameResult& r : results) {
        std::printf("frame %d: %s\n", r.frame, r.line.c_str());
        failed += !r.pass;
    }
    std::printf("%s: %zu frames, %d differ; renderer %s; comparison %.2f ms per frame\n", sc.name.c_str(),
                results.size(), failed, rendererText(renderer).c_str(),
                results.empty() ? 0.0 : 1e3 * compareSeconds / static_cast<double>(results.size()));
    if (!a.junit.empty()) writeJunit(a.junit, sc, results, failed, renderer, goldenRenderer);
    return failed ? 1 : 0;
}
#endif

}  // namespace

void addCheckCommand(CLI::App& app) {
    auto a = std::make_shared<CheckArgs>();
    CLI::App* cmd = app.add_subcommand(
        "check", "Screenshot test: run a scene offscreen and compare frames with golden PNGs. Exit codes: 0 all frames "
                 "pass, 1 a frame differs (or has no golden image), 2 bad input (also no goldens in the folder), 3 "
                 "diverged, 4 refused step");
    cmd->add_option("scene", a->scene, "Scene file (JSON, see docs/scene-format.md)")->required();
    cmd->add_option("--golden", a->golden, "Folder of golden frames (frame_NNNNNN.png and golden.json)")->required();
    cmd->add_option("--frames", a->frames,
                    "Frames to compare, e.g. 0,15,last (default: capture.check.frames, else the goldens' frames; "
                    "with --update every frame)");
    a->toleranceOpt = cmd->add_option("--tolerance", a->tolerance,
                                      "A pixel fails when a channel differs by more than this (0-255, default "
                                      "capture.check.max_diff, else 5)")
                          ->check(CLI::Range(0, 255));
    a->maxFailingOpt = cmd->add_option("--max-failing", a->maxFailing,
                                       "A frame fails when more than this share of its pixels fail (default "
                                       "capture.check.max_failing, else 0.001)")
                           ->check(CLI::Range(0.0, 1.0));
    cmd->add_flag("--update", a->update, "Write the frames as the goldens instead of comparing");
    cmd->add_option("--junit", a->junit, "Write a JUnit XML report here");
    cmd->add_option("--out", a->out,
                    "Folder for this run's frames, report.json and, per failing frame, the diff and side-by-side "
                    "images (default check_out)");
    cmd->add_option("--set", a->sets, "Override a scene value: key.path=value (JSON value)");
    cmd->add_option("--threads", a->threads, "Worker threads (0: chosen by measuring)")->check(CLI::Range(0, 1024));
    cmd->callback([a] {
#ifdef CUTSIM_HAVE_RENDER
        runCommand([&] { return runCheck(*a); });
#else
        needsRenderer();
#endif
    });
}

}  // namespace cutsim::app
