#include "png_writer.hpp"

// Debian's libstb (linked through pkg-config imgui) already holds the stb implementations, so
// only the declarations are included here; defining STB_*_IMPLEMENTATION would duplicate symbols.
#include <stb_image.h>
#include <stb_image_write.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <vector>

namespace cutsim::render {

void writePng(const std::string& path, const Image& img) {
    if (img.width <= 0 || img.height <= 0 || img.rgba.size() != 4 * static_cast<size_t>(img.width) * img.height)
        throw std::runtime_error("cannot write " + path + ": empty or inconsistent image");
    // Encode to memory first, so a failing folder is reported by the file write below.
    std::vector<unsigned char> png;
    auto sink = [](void* ctx, void* data, int size) {
        auto* out = static_cast<std::vector<unsigned char>*>(ctx);
        out->insert(out->end(), static_cast<unsigned char*>(data), static_cast<unsigned char*>(data) + size);
    };
    if (!stbi_write_png_to_func(sink, &png, img.width, img.height, 4, img.rgba.data(), 4 * img.width))
        throw std::runtime_error("cannot encode PNG " + path);
    const std::string tmp = path + ".tmp";
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) throw std::runtime_error("cannot write " + path + ": " + std::strerror(errno));
    const bool ok = std::fwrite(png.data(), 1, png.size(), f) == png.size();
    const bool closed = std::fclose(f) == 0;
    if (!ok || !closed) {
        std::remove(tmp.c_str());
        throw std::runtime_error("cannot write " + path + ": write failed (disk full?)");
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        const int e = errno;
        std::remove(tmp.c_str());
        throw std::runtime_error("cannot rename to " + path + ": " + std::strerror(e));
    }
}

Image readPng(const std::string& path) {
    int w = 0, h = 0, c = 0;
    unsigned char* data = stbi_load(path.c_str(), &w, &h, &c, 4);
    if (!data) throw std::runtime_error("cannot read PNG " + path + ": " + stbi_failure_reason());
    Image img;
    img.width = w;
    img.height = h;
    img.rgba.assign(data, data + 4 * static_cast<size_t>(w) * h);
    stbi_image_free(data);
    return img;
}

PngWriter::PngWriter(std::size_t capacity) : capacity_(capacity ? capacity : 1), thread_([this] { run(); }) {}

PngWriter::~PngWriter() {
    {
        std::lock_guard lock(mutex_);
        stop_ = true;
    }
    changed_.notify_all();
    thread_.join();
}

void PngWriter::rethrow() {
    if (error_) {
        auto e = error_;
        error_ = nullptr;
        std::rethrow_exception(e);
    }
}

void PngWriter::push(std::string path, Image img) {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return queue_.size() < capacity_ || error_; });
    rethrow();
    queue_.emplace_back(std::move(path), std::move(img));
    changed_.notify_all();
}

void PngWriter::flush() {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return (queue_.empty() && !busy_) || error_; });
    rethrow();
}

std::size_t PngWriter::written() const {
    std::lock_guard lock(mutex_);
    return written_;
}

void PngWriter::run() {
    std::unique_lock lock(mutex_);
    for (;;) {
        changed_.wait(lock, [&] { return stop_ || !queue_.empty(); });
        if (queue_.empty()) return; // stop requested and nothing left
        auto job = std::move(queue_.front());
        queue_.pop_front();
        busy_ = true;
        lock.unlock();
        std::exception_ptr err;
        try {
            writePng(job.first, job.second);
        } catch (...) {
            err = std::current_exception();
        }
        lock.lock();
        busy_ = false;
        if (err) {
            if (!error_) error_ = err; // the first error is the informative one
        } else {
            ++written_;
        }
        changed_.notify_all();
    }
}

} // namespace cutsim::render
