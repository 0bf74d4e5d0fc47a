// MP4 video through the ffmpeg program: frames converted to yuv420p here and piped raw to its
// stdin, H.264 out. Frames go to the pipe from a writer thread, so the caller does not wait while
// ffmpeg encodes.
#pragma once

#include "image.hpp"

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace cutsim::render {

// Full path of an executable found on PATH, or "" when there is none.
std::string findOnPath(const std::string& program);

// An RGBA image (even width and height) as planar yuv420p into out (resized): BT.601 with 8-bit
// studio range (Y 16..235, U and V 16..240 around 128) in fixed point (ITU-R BT.601, the 8-bit
// integer form of its equations), U and V of each 2x2 block's mean colour; alpha is ignored.
// What ffmpeg's own conversion gives an H.264 stream without colour tags, at a third of the
// bytes through the pipe.
void rgbaToYuv420(const Image& img, std::vector<std::uint8_t>& out);

class VideoEncoder {
public:
    // Starts ffmpeg writing path.tmp (renamed to path by finish). Width and height must be even
    // (yuv420p). Throws std::runtime_error when ffmpeg is not on PATH or cannot start.
    VideoEncoder(const std::string& path, int width, int height, double fps = 30);
    ~VideoEncoder();  // without finish: stops ffmpeg and removes the temporary file
    VideoEncoder(const VideoEncoder&) = delete;
    VideoEncoder& operator=(const VideoEncoder&) = delete;

    // Converts a frame (rgbaToYuv420) and queues it (blocks while 4 wait); throws if the size
    // differs or ffmpeg stopped.
    void addFrame(const Image& img);
    // Makes the buffers of the frames that can be in flight (converted, queued, written) now, so
    // that the first frames do not page-fault them in.
    void reserve();
    void finish();                          // waits for ffmpeg, renames; throws with its exit status
    int frames() const { return frames_; }  // frames written to ffmpeg

private:
    void run();                                // writer thread
    void stopWriter();                         // lets the writer finish the queue and joins it
    static constexpr std::size_t kQueued = 4;  // frames waiting for the writer at most
    std::string path_, tmp_;
    int width_, height_;
    std::atomic<int> frames_ = 0;
    std::FILE* pipe_ = nullptr;
    std::mutex mutex_;
    std::condition_variable changed_;
    std::deque<std::vector<std::uint8_t>> queue_;   // yuv420p frames
    std::vector<std::vector<std::uint8_t>> spare_;  // written ones kept for reuse (a frame-sized
                                                    // allocation page-faults)
    bool stop_ = false, failed_ = false;
    std::thread writer_;
};

}  // namespace cutsim::render
