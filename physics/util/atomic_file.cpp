#include "util/atomic_file.hpp"

#include "util/input_error.hpp"

#include <filesystem>
#include <fstream>

namespace cutsim {

void writeFileAtomic(const std::string& path, std::string_view content) {
    const std::string tmp = path + ".tmp";
    std::error_code ec;
    {
        std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
        if (!f) throw InputError(path, 0, "cannot write (folder missing or not writable)");
        f.write(content.data(), static_cast<std::streamsize>(content.size()));
        f.close();
        if (!f) {
            std::filesystem::remove(tmp, ec);
            throw InputError(path, 0, "write failed (disk full?)");
        }
    }
    std::filesystem::rename(tmp, path, ec);
    if (ec) {
        std::error_code ignored;
        std::filesystem::remove(tmp, ignored);
        throw InputError(path, 0, "cannot replace file: " + ec.message());
    }
}

}  // namespace cutsim
