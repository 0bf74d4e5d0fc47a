#include "png_writer.hpp"

// Writing: the PNG's chunks here, its zlib stream by libdeflate (faster than zlib at the same
// level, and smaller: docs/build.md); reading through stb. Debian's libstb (linked through
// pkg-config imgui) already holds the stb implementation, so only its declarations are here.
#include <libdeflate.h>
#include <stb_image.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <algorithm>
#include <memory>
#include <stdexcept>
#include <vector>

namespace cutsim::render {

namespace {

void put32(std::vector<unsigned char>& out, std::uint32_t v) {
    for (int s = 24; s >= 0; s -= 8) out.push_back(static_cast<unsigned char>(v >> s));
}

// A chunk: length, type, data, CRC-32 of type and data (PNG spec, sec. 5.3).
void chunk(std::vector<unsigned char>& out, const char type[4], const unsigned char* data, size_t n) {
    put32(out, static_cast<std::uint32_t>(n));
    const size_t at = out.size();
    out.insert(out.end(), type, type + 4);
    out.insert(out.end(), data, data + n);
    put32(out, libdeflate_crc32(0, out.data() + at, n + 4));
}

struct CompressorDeleter {
    void operator()(libdeflate_compressor* c) const { libdeflate_free_compressor(c); }
};

// Lossless PNG, 8-bit RGB (opaque) or RGBA, every row unfiltered, deflate level 1: rendered frames
// are mostly flat background, which compresses as well unfiltered, and filtering costs more time
// than it saves bytes. The scanlines and the stream are kept per thread (a frame-sized buffer
// fresh each frame is page faults).
void encodePng(const Image& img, bool opaque, std::vector<unsigned char>& out) {
    thread_local std::unique_ptr<libdeflate_compressor, CompressorDeleter> compressor(libdeflate_alloc_compressor(1));
    thread_local std::vector<unsigned char> raw, z;
    if (!compressor) throw std::bad_alloc();
    const size_t w = static_cast<size_t>(img.width), h = static_cast<size_t>(img.height), px = opaque ? 3 : 4;
    raw.resize(h * (1 + px * w));
    unsigned char* r = raw.data();
    for (size_t y = 0; y < h; ++y) {
        *r++ = 0;  // filter type None
        const unsigned char* src = img.rgba.data() + 4 * w * y;
        if (opaque) {
            for (size_t x = 0; x < w; ++x, r += 3, src += 4) r[0] = src[0], r[1] = src[1], r[2] = src[2];
        } else {
            std::memcpy(r, src, 4 * w);
            r += 4 * w;
        }
    }
    z.resize(libdeflate_zlib_compress_bound(compressor.get(), raw.size()));
    const size_t zn = libdeflate_zlib_compress(compressor.get(), raw.data(), raw.size(), z.data(), z.size());
    if (zn == 0) throw std::runtime_error("deflate found no room");  // cannot happen: the bound is room
    static constexpr unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    out.assign(kSignature, kSignature + 8);
    std::vector<unsigned char> ihdr;
    put32(ihdr, static_cast<std::uint32_t>(w));
    put32(ihdr, static_cast<std::uint32_t>(h));
    ihdr.insert(ihdr.end(), {8, static_cast<unsigned char>(opaque ? 2 : 6), 0, 0, 0});  // depth, colour type
    chunk(out, "IHDR", ihdr.data(), ihdr.size());
    chunk(out, "IDAT", z.data(), zn);
    chunk(out, "IEND", nullptr, 0);
}

}  // namespace

void writePng(const std::string& path, const Image& img) {
    if (img.width <= 0 || img.height <= 0 || img.rgba.size() != 4 * static_cast<size_t>(img.width) * img.height)
        throw std::runtime_error("cannot write " + path + ": empty or inconsistent image");
    // Encode to memory first, so a failing folder is reported by the file write below.
    thread_local std::vector<unsigned char> png;  // kept: a fresh one is page faults each frame
    bool opaque = true;
    for (size_t i = 3; i < img.rgba.size() && opaque; i += 4) opaque = img.rgba[i] == 255;
    try {
        encodePng(img, opaque, png);
    } catch (const std::exception& e) {
        throw std::runtime_error("cannot encode PNG " + path + ": " + e.what());
    }
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

PngWriter::PngWriter(std::size_t capacity, unsigned threads) : capacity_(capacity ? capacity : 1) {
    if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
    for (unsigned i = 0; i < threads; ++i) threads_.emplace_back([this] { run(); });
}

PngWriter::~PngWriter() {
    {
        std::lock_guard lock(mutex_);
        stop_ = true;
    }
    changed_.notify_all();
    for (auto& t : threads_) t.join();
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
    changed_.wait(lock, [&] { return (queue_.empty() && busy_ == 0) || error_; });
    rethrow();
}

Image PngWriter::spare() {
    std::lock_guard lock(mutex_);
    if (spare_.empty()) return {};
    Image img = std::move(spare_.back());
    spare_.pop_back();
    return img;
}

void PngWriter::reserve(std::size_t count, int width, int height) {
    std::lock_guard lock(mutex_);
    while (spare_.size() < std::min(count, capacity_)) {
        Image& img = spare_.emplace_back();
        img.width = width;
        img.height = height;
        img.rgba.resize(4 * static_cast<size_t>(width) * static_cast<size_t>(height));
    }
}

std::size_t PngWriter::written() const {
    std::lock_guard lock(mutex_);
    return written_;
}

void PngWriter::run() {
    std::unique_lock lock(mutex_);
    for (;;) {
        changed_.wait(lock, [&] { return stop_ || !queue_.empty(); });
        if (queue_.empty()) return;  // stop requested and nothing left
        auto job = std::move(queue_.front());
        queue_.pop_front();
        ++busy_;
        lock.unlock();
        std::exception_ptr err;
        try {
            writePng(job.first, job.second);
        } catch (...) {
            err = std::current_exception();
        }
        lock.lock();
        --busy_;
        if (err) {
            if (!error_) error_ = err;  // the first error is the informative one
        } else {
            ++written_;
        }
        if (spare_.size() < capacity_) spare_.push_back(std::move(job.second));
        changed_.notify_all();
    }
}

}  // namespace cutsim::render
