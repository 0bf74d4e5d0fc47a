#include "video.hpp"

#include <csignal>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

namespace cutsim::render {

std::string findOnPath(const std::string& program) {
    const char* path = std::getenv("PATH");
    if (!path || !*path) return {};
    std::stringstream dirs(path);
    std::string dir;
    while (std::getline(dirs, dir, ':')) {
        if (dir.empty()) continue;  // an empty entry would mean the current folder: not trusted
        const std::string full = dir + "/" + program;
        if (::access(full.c_str(), X_OK) == 0) return full;
    }
    return {};
}

void rgbaToYuv420(const Image& img, std::vector<std::uint8_t>& out) {
    const size_t w = static_cast<size_t>(img.width), h = static_cast<size_t>(img.height);
    out.resize(w * h + 2 * (w / 2) * (h / 2));
    std::uint8_t* yp = out.data();
    std::uint8_t* up = yp + w * h;
    std::uint8_t* vp = up + (w / 2) * (h / 2);
    const std::uint8_t* px = img.rgba.data();
    for (size_t y = 0; y < h; ++y) {
        const std::uint8_t* row = px + 4 * w * y;
        std::uint8_t* yr = yp + w * y;
        for (size_t x = 0; x < w; ++x) {
            const int r = row[4 * x], g = row[4 * x + 1], b = row[4 * x + 2];
            yr[x] = static_cast<std::uint8_t>(((66 * r + 129 * g + 25 * b + 128) >> 8) + 16);
        }
    }
    for (size_t y = 0; y + 1 < h; y += 2) {
        const std::uint8_t* r0 = px + 4 * w * y;
        const std::uint8_t* r1 = r0 + 4 * w;
        std::uint8_t* ur = up + (w / 2) * (y / 2);
        std::uint8_t* vr = vp + (w / 2) * (y / 2);
        for (size_t x = 0; x < w / 2; ++x) {
            const std::uint8_t *a = r0 + 8 * x, *c = r1 + 8 * x;
            const int r = (a[0] + a[4] + c[0] + c[4] + 2) >> 2, g = (a[1] + a[5] + c[1] + c[5] + 2) >> 2,
                      b = (a[2] + a[6] + c[2] + c[6] + 2) >> 2;
            ur[x] = static_cast<std::uint8_t>(((-38 * r - 74 * g + 112 * b + 128) >> 8) + 128);
            vr[x] = static_cast<std::uint8_t>(((112 * r - 94 * g - 18 * b + 128) >> 8) + 128);
        }
    }
}

namespace {
// Single-quoted for /bin/sh.
std::string shellQuote(const std::string& s) {
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}
}  // namespace

VideoEncoder::VideoEncoder(const std::string& path, int width, int height, double fps)
    : path_(path), tmp_(path + ".tmp"), width_(width), height_(height) {
    if (width <= 0 || height <= 0 || width % 2 || height % 2)
        throw std::runtime_error("video size must be positive and even (H.264 yuv420p), got " + std::to_string(width) +
                                 "x" + std::to_string(height));
    const std::string ffmpeg = findOnPath("ffmpeg");
    if (ffmpeg.empty())
        throw std::runtime_error("cannot write video " + path +
                                 ": the ffmpeg program is not on PATH (install it, e.g. apt-get install ffmpeg)");
    // ultrafast on one thread: about a third of veryfast's CPU per frame for the same quality at a
    // larger file, and one thread is what a frame stream beside rendering and physics can spare.
    // A dying ffmpeg must give a write error here, not kill the simulation with SIGPIPE.
    std::signal(SIGPIPE, SIG_IGN);
    // glibc's malloc may map each frame's 1.4 MB packet afresh and page-fault it in (in `cutsim run`
    // a third of ffmpeg's CPU): frames come from its heap instead.
    std::ostringstream cmd;
    cmd << "GLIBC_TUNABLES=\"${GLIBC_TUNABLES:+$GLIBC_TUNABLES:}glibc.malloc.mmap_threshold=67108864\" "
        << shellQuote(ffmpeg) << " -hide_banner -loglevel error -y -f rawvideo -pix_fmt yuv420p -s " << width << "x"
        << height << " -r " << fps << " -i - -c:v libx264 -preset ultrafast -threads 1 -pix_fmt yuv420p -f mp4 "
        << shellQuote(tmp_);
    pipe_ = ::popen(cmd.str().c_str(), "w");
    if (!pipe_) throw std::runtime_error("cannot start ffmpeg for " + path);
    // A frame in few pipe fills instead of one each 64 KiB (Linux's default): every fill is a
    // switch to ffmpeg and back. Where the system allows less, the default stays.
    ::fcntl(::fileno(pipe_), F_SETPIPE_SZ, 1 << 20);
    writer_ = std::thread([this] { run(); });
}

void VideoEncoder::run() {
    std::unique_lock lock(mutex_);
    for (;;) {
        changed_.wait(lock, [&] { return stop_ || !queue_.empty(); });
        if (queue_.empty()) return;  // stop requested and nothing left
        std::vector<std::uint8_t> frame = std::move(queue_.front());
        queue_.pop_front();
        changed_.notify_all();
        if (failed_) continue;  // drain: ffmpeg is gone
        lock.unlock();
        const bool ok = std::fwrite(frame.data(), 1, frame.size(), pipe_) == frame.size();
        lock.lock();
        if (ok)
            ++frames_;
        else
            failed_ = true;
        if (spare_.size() < kQueued + 2) spare_.push_back(std::move(frame));
        changed_.notify_all();
    }
}

void VideoEncoder::stopWriter() {
    if (!writer_.joinable()) return;
    {
        std::lock_guard lock(mutex_);
        stop_ = true;
    }
    changed_.notify_all();
    writer_.join();
}

VideoEncoder::~VideoEncoder() {
    stopWriter();
    if (pipe_) {
        ::pclose(pipe_);
        std::remove(tmp_.c_str());
    }
}

void VideoEncoder::addFrame(const Image& img) {
    if (!pipe_) throw std::runtime_error("video " + path_ + " already finished");
    if (img.width != width_ || img.height != height_)
        throw std::runtime_error("video frame is " + std::to_string(img.width) + "x" + std::to_string(img.height) +
                                 ", the video " + std::to_string(width_) + "x" + std::to_string(height_));
    std::vector<std::uint8_t> frame;
    {
        std::lock_guard lock(mutex_);
        if (!spare_.empty()) {
            frame = std::move(spare_.back());
            spare_.pop_back();
        }
    }
    rgbaToYuv420(img, frame);
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return queue_.size() < kQueued || failed_; });
    if (failed_) throw std::runtime_error("ffmpeg stopped while writing " + path_);
    queue_.push_back(std::move(frame));
    changed_.notify_all();
}

void VideoEncoder::reserve() {
    const size_t w = static_cast<size_t>(width_), h = static_cast<size_t>(height_);
    std::lock_guard lock(mutex_);
    // one being converted, kQueued waiting, one being written
    while (spare_.size() < kQueued + 2) spare_.emplace_back(w * h + 2 * (w / 2) * (h / 2));
}

void VideoEncoder::finish() {
    if (!pipe_) return;
    stopWriter();
    if (failed_) {
        ::pclose(pipe_);
        pipe_ = nullptr;
        std::remove(tmp_.c_str());
        throw std::runtime_error("ffmpeg stopped while writing " + path_);
    }
    const int status = ::pclose(pipe_);
    pipe_ = nullptr;
    if (status == -1 || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        std::remove(tmp_.c_str());
        throw std::runtime_error("ffmpeg failed writing " + path_ + " (exit status " +
                                 std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) + ")");
    }
    if (std::rename(tmp_.c_str(), path_.c_str()) != 0) {
        std::remove(tmp_.c_str());
        throw std::runtime_error("cannot rename video to " + path_);
    }
}

}  // namespace cutsim::render
