// The shared options and result files of `cutsim bench` (options.hpp).
#include "bench/options.hpp"
#include "bench/machine.hpp"
#include "util/atomic_file.hpp"
#include "util/json_text.hpp"

#include <nlohmann/json.hpp>

#include <iostream>
#include <sstream>

namespace cutsim::bench {

void jsonFlag(CLI::App& c, bool& json, const std::string& keys, bool machine) {
    c.add_flag("--json", json,
               "Print " + keys +
                   (machine ? "; machine: {cpu, cores, load_average, load_average_end} (1, 5, 15 min)" : ""));
}

void tinyFlag(CLI::App& c, bool& tiny, const std::string& what) { c.add_flag("--tiny", tiny, "Test size: " + what); }

void csvOption(CLI::App& c, std::string& path, const std::string& what) {
    c.add_option("--csv", path, "Write the " + what + " to this CSV file");
}

void plotOption(CLI::App& c, std::string& path, const std::string& what) {
    c.add_option("--plot", path, "Draw " + what + " to this PNG (needs gnuplot)");
}

CLI::Option* threadsOption(CLI::App& c, int& threads, const std::string& description, int least) {
    return c.add_option("--threads", threads, description)->check(CLI::Range(least, 1024));
}

void printJson(const nlohmann::json& j) { std::cout << jsonText(j); }

void printResult(nlohmann::json j, const nlohmann::json& machine) {
    j["machine"] = machine;
    j["machine"]["load_average_end"] = loadAverage();
    printJson(j);
}

std::string csvText(const nlohmann::json& rows, const std::vector<std::string>& columns, bool header) {
    std::ostringstream c;
    if (header) {
        for (size_t k = 0; k < columns.size(); ++k) c << (k ? "," : "") << columns[k].substr(columns[k].rfind('/') + 1);
        c << '\n';
    }
    for (const nlohmann::json& r : rows) {
        for (size_t k = 0; k < columns.size(); ++k) {
            if (k) c << ',';
            const nlohmann::json::json_pointer p("/" + columns[k]);
            if (!r.contains(p)) continue;
            const nlohmann::json& v = r.at(p);
            if (v.is_string())
                c << v.get<std::string>();
            else
                c << v;
        }
        c << '\n';
    }
    return c.str();
}

void writeCsv(const std::string& path, const nlohmann::json& rows, const std::vector<std::string>& columns) {
    writeFileAtomic(path, csvText(rows, columns));
}

}  // namespace cutsim::bench
