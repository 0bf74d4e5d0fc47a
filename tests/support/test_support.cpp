#include "test_support.hpp"

#include "mesh/generate.hpp"

#include <Eigen/Eigenvalues>
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

std::string workDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    const std::string name = std::string(info->test_suite_name()) + "_" + info->name();
    const auto dir =
        std::filesystem::temp_directory_path() / ("cutsim_work_" + name + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir.string();
}

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

TetMesh unitTet() {
    TetMesh m;
    m.X.resize(3, 4);
    m.X << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
    m.tets.resize(4, 1);
    m.tets << 0, 1, 2, 3;
    return m;
}

TetMesh boxMesh(double lx, double ly, double lz, int nx, int ny, int nz) {
    return cutsim::boxMesh(lx, ly, lz, nx, ny, nz);
}

std::string writeText(const std::string& path, const std::string& text) {
    std::ofstream(path, std::ios::binary) << text;
    return path;
}

std::string readText(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

double denseLambdaMax(const Model& m) {
    const Eigen::MatrixXd K = Eigen::MatrixXd(assembleStiffness(m));
    std::vector<int> dofs;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.invMass(i) > 0)
            for (int k = 0; k < 3; ++k) dofs.push_back(3 * i + k);
    const int n = static_cast<int>(dofs.size());
    Eigen::MatrixXd A(n, n);
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c)
            A(r, c) = K(dofs[r], dofs[c]) * std::sqrt(m.invMass(dofs[r] / 3) * m.invMass(dofs[c] / 3));
    return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(A, Eigen::EigenvaluesOnly).eigenvalues().maxCoeff();
}

int runCutsim(const std::string& args, std::string* out, std::string* err) {
    // its own folder: tempDir() would wipe files the test prepared for the command
    const auto dir = std::filesystem::temp_directory_path() / ("cutsim_run_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    const std::string o = (dir / "stdout.txt").string(), e = (dir / "stderr.txt").string();
    const std::string cmd = std::string(CUTSIM_BINARY) + " " + args + " >" + o + " 2>" + e;
    const int status = std::system(cmd.c_str());
    if (out) *out = readText(o);
    if (err) *err = readText(e);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

double boundaryArea(const TetMesh& m) {
    const Eigen::Matrix3Xi F = boundaryFaces(m);
    double a = 0;
    for (Eigen::Index f = 0; f < F.cols(); ++f)
        a += 0.5 * (m.X.col(F(1, f)) - m.X.col(F(0, f))).cross(m.X.col(F(2, f)) - m.X.col(F(0, f))).norm();
    return a;
}

void fixBelow(Model& m, int axis, double value) {
    std::vector<int> nodes;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.X(axis, i) < value) nodes.push_back(i);
    fixNodes(m, nodes);
}

}  // namespace cutsim::test
