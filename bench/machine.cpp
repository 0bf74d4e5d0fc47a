#include "bench/machine.hpp"

#include <nlohmann/json.hpp>

#include <cstdlib>
#include <fstream>
#include <string>
#include <thread>

namespace cutsim {

namespace {

// The "model name" of /proc/cpuinfo's first processor; empty elsewhere.
std::string cpuModel() {
    std::ifstream f("/proc/cpuinfo");
    std::string line;
    while (std::getline(f, line))
        if (line.rfind("model name", 0) == 0) {
            const size_t colon = line.find(':');
            return colon == std::string::npos ? "" : line.substr(line.find_first_not_of(' ', colon + 1));
        }
    return "";
}

}  // namespace

nlohmann::json loadAverage() {
    double l[3];
    nlohmann::json j = nlohmann::json::array();
    if (getloadavg(l, 3) == 3)
        for (double v : l) j.push_back(v);
    return j;
}

nlohmann::json machineJson() {
    return {{"cpu", cpuModel()}, {"cores", std::thread::hardware_concurrency()}, {"load_average", loadAverage()}};
}

}  // namespace cutsim
