#include "png_writer.hpp"

// Writing through libpng (speed, see encodePng); reading through stb. Debian's libstb (linked
// through pkg-config imgui) already holds the stb implementation, so only its declarations are here.
#include <png.h>
#include <stb_image.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <algorithm>
#include <stdexcept>
#include <vector>

namespace cutsim::render {

namespace {

// libpng reports errors by longjmp: keep the message, then jump back to encode's setjmp.
void onPngError(png_structp png, png_const_charp msg) {
    if (auto* err = static_cast<char*>(png_get_error_ptr(png))) std::snprintf(err, 256, "%s", msg);
    png_longjmp(png, 1);
}
void onPngWarning(png_structp, png_const_charp) {}
void appendBytes(png_structp png, png_bytep data, png_size_t n) {
    auto* out = static_cast<std::vector<unsigned char>*>(png_get_io_ptr(png));
    out->insert(out->end(), data, data + n);
}
void noFlush(png_structp) {}

// Lossless PNG at zlib level 1 without filtering: much faster than level 6 with adaptive filters
// (or stb's encoder) on rendered frames, for files of about the same size as stb's (the
// flat background compresses as well unfiltered); an opaque image as RGB, a quarter less to
// compress. No object with a destructor lives in this frame, so the longjmp skips nothing.
bool encodePng(const Image& img, bool opaque, std::vector<unsigned char>* out, char* err) {
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, err, onPngError, onPngWarning);
    if (!png) return false;
    png_infop info = png_create_info_struct(png);
    if (!info || setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        return false;
    }
    png_set_write_fn(png, out, appendBytes, noFlush);
    png_set_IHDR(png, info, static_cast<png_uint_32>(img.width), static_cast<png_uint_32>(img.height), 8,
                 opaque ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_RGBA, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
                 PNG_FILTER_TYPE_DEFAULT);
    png_set_compression_level(png, 1);
    png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_NONE);
    png_write_info(png, info);
    if (opaque) png_set_filler(png, 0, PNG_FILLER_AFTER);  // rows stay RGBA; the alpha byte is dropped
    const size_t row = 4 * static_cast<size_t>(img.width);
    for (int y = 0; y < img.height; ++y) png_write_row(png, img.rgba.data() + row * static_cast<size_t>(y));
    png_write_end(png, nullptr);
    png_destroy_write_struct(&png, &info);
    return true;
}

}  // namespace

void writePng(const std::string& path, const Image& img) {
    if (img.width <= 0 || img.height <= 0 || img.rgba.size() != 4 * static_cast<size_t>(img.width) * img.height)
        throw std::runtime_error("cannot write " + path + ": empty or inconsistent image");
    // Encode to memory first, so a failing folder is reported by the file write below.
    thread_local std::vector<unsigned char> png;  // kept: a fresh one is page faults each frame
    png.clear();
    png.reserve(img.rgba.size() / 8);
    char err[256] = "libpng failed";
    bool opaque = true;
    for (size_t i = 3; i < img.rgba.size() && opaque; i += 4) opaque = img.rgba[i] == 255;
    if (!encodePng(img, opaque, &png, err)) throw std::runtime_error("cannot encode PNG " + path + ": " + err);
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
