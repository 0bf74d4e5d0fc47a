// MP4 video through the ffmpeg program: raw RGBA frames piped to its stdin, H.264 out.
#pragma once

#include "image.hpp"

#include <cstdio>
#include <string>

namespace cutsim::render {

// Full path of an executable found on PATH, or "" when there is none.
std::string findOnPath(const std::string& program);

class VideoEncoder {
public:
    // Starts ffmpeg writing path.tmp (renamed to path by finish). Width and height must be even
    // (yuv420p). Throws std::runtime_error when ffmpeg is not on PATH or cannot start.
    VideoEncoder(const std::string& path, int width, int height, double fps = 30);
    ~VideoEncoder(); // without finish: stops ffmpeg and removes the temporary file
    VideoEncoder(const VideoEncoder&) = delete;
    VideoEncoder& operator=(const VideoEncoder&) = delete;

    void addFrame(const Image& img); // throws if the size differs or ffmpeg stopped
    void finish();                   // waits for ffmpeg, renames; throws with its exit status
    int frames() const { return frames_; }

private:
    std::string path_, tmp_;
    int width_, height_;
    int frames_ = 0;
    std::FILE* pipe_ = nullptr;
};

} // namespace cutsim::render
