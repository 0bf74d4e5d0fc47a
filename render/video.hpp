// MP4 video through the ffmpeg program: raw RGBA frames piped to its stdin, H.264 out. Frames go
// to the pipe from a writer thread, so the caller does not wait while ffmpeg encodes.
#pragma once

#include "image.hpp"

#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace cutsim::render {

// Full path of an executable found on PATH, or "" when there is none.
std::string findOnPath(const std::string& program);

class VideoEncoder {
public:
    // Starts ffmpeg writing path.tmp (renamed to path by finish). Width and height must be even
    // (yuv420p). Throws std::runtime_error when ffmpeg is not on PATH or cannot start.
    VideoEncoder(const std::string& path, int width, int height, double fps = 30);
    ~VideoEncoder();  // without finish: stops ffmpeg and removes the temporary file
    VideoEncoder(const VideoEncoder&) = delete;
    VideoEncoder& operator=(const VideoEncoder&) = delete;

    // Queues a frame (blocks while 4 wait); throws if the size differs or ffmpeg stopped.
    void addFrame(Image img);
    // A frame whose pixels were written, to be filled again (its buffer reused), or an empty one.
    Image spareFrame();
    void finish();                          // waits for ffmpeg, renames; throws with its exit status
    int frames() const { return frames_; }  // frames written to ffmpeg

private:
    void run();         // writer thread
    void stopWriter();  // lets the writer finish the queue and joins it
    std::string path_, tmp_;
    int width_, height_;
    std::atomic<int> frames_ = 0;
    std::FILE* pipe_ = nullptr;
    std::mutex mutex_;
    std::condition_variable changed_;
    std::deque<Image> queue_;
    std::vector<Image> spare_;  // written frames kept for reuse (a frame-sized allocation page-faults)
    bool stop_ = false, failed_ = false;
    std::thread writer_;
};

}  // namespace cutsim::render
