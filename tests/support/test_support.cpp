#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <sys/wait.h>
#include <unistd.h>

namespace cutsim::test {

std::string data(const std::string& rel) { return std::string(CUTSIM_DATA_DIR) + "/" + rel; }
std::string source(const std::string& rel) { return std::string(CUTSIM_SOURCE_DIR) + "/" + rel; }

std::string tempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = info ? std::string(info->test_suite_name()) + "_" + info->name() : "cutsim";
    for (char& c : name)
        if (c == '/') c = '_';
    auto dir = std::filesystem::temp_directory_path() / ("cutsim_test_" + name + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir.string();
}

TetMesh boxMesh(double lx, double ly, double lz, int nx, int ny, int nz) {
    TetMesh m;
    const int px = nx + 1, py = ny + 1, pz = nz + 1;
    m.X.resize(3, px * py * pz);
    auto id = [&](int i, int j, int k) { return i + px * (j + py * k); };
    for (int k = 0; k < pz; ++k)
        for (int j = 0; j < py; ++j)
            for (int i = 0; i < px; ++i)
                m.X.col(id(i, j, k)) << lx * i / nx, ly * j / ny, lz * k / nz;
    // Kuhn (Freudenthal) split: 6 tets along the cube diagonal 0 -> 7, one per axis permutation.
    static constexpr int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    m.tets.resize(4, 6 * nx * ny * nz);
    int t = 0;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i)
                for (const auto& p : perms) {
                    int c[3] = {i, j, k};
                    int v[4];
                    v[0] = id(c[0], c[1], c[2]);
                    for (int s = 0; s < 3; ++s) {
                        ++c[p[s]];
                        v[s + 1] = id(c[0], c[1], c[2]);
                    }
                    m.tets.col(t) << v[0], v[1], v[2], v[3];
                    if (tetSignedVolume(m, t) < 0) std::swap(m.tets(2, t), m.tets(3, t));
                    ++t;
                }
    m.source = "box";
    return m;
}

int runCutsim(const std::string& args, std::string* out, std::string* err) {
    const std::string dir = tempDir();
    const std::string o = dir + "/stdout.txt", e = dir + "/stderr.txt";
    const std::string cmd = std::string(CUTSIM_BINARY) + " " + args + " >" + o + " 2>" + e;
    const int status = std::system(cmd.c_str());
    auto slurp = [](const std::string& p) {
        std::ifstream in(p);
        std::stringstream ss;
        ss << in.rdbuf();
        return ss.str();
    };
    if (out) *out = slurp(o);
    if (err) *err = slurp(e);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

} // namespace cutsim::test
