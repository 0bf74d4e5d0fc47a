// PNG files: a synchronous writer, a reader for tests, and a background writer so encoding does
// not stall the simulation thread.
#pragma once

#include "image.hpp"

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace cutsim::render {

// Writes img to path through path.tmp renamed at the end (a reader never sees half a file).
// Throws std::runtime_error naming the path on failure.
void writePng(const std::string& path, const Image& img);

// Reads a PNG as RGBA. Throws std::runtime_error naming the path on failure.
Image readPng(const std::string& path);

// Writes PNGs on a pool of threads. push blocks while `capacity` frames wait, which bounds memory
// when encoding is slower than rendering. A write error is rethrown by the next push or flush.
class PngWriter {
public:
    // threads = 0: one per core.
    explicit PngWriter(std::size_t capacity = 4, unsigned threads = 0);
    ~PngWriter();  // finishes the queued frames; errors there are dropped (call flush to see them)
    PngWriter(const PngWriter&) = delete;
    PngWriter& operator=(const PngWriter&) = delete;

    void push(std::string path, Image img);
    // A written frame, to be filled again (its buffer reused), or an empty one.
    Image spare();
    // Makes `count` spare frames of this size now (at most the capacity), so that the first frames
    // do not page-fault their buffers in.
    void reserve(std::size_t count, int width, int height);
    void flush();  // waits until every queued frame is written
    std::size_t written() const;

private:
    void run();
    void rethrow();  // with the lock held
    std::size_t capacity_;
    mutable std::mutex mutex_;
    std::condition_variable changed_;
    std::deque<std::pair<std::string, Image>> queue_;
    std::vector<Image> spare_;  // written frames kept for reuse (a frame-sized allocation page-faults)
    int busy_ = 0;              // frames being encoded
    bool stop_ = false;
    std::size_t written_ = 0;
    std::exception_ptr error_;
    std::vector<std::thread> threads_;
};

}  // namespace cutsim::render
