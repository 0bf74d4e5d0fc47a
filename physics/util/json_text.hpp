// JSON written by the project: indented, and valid whatever bytes a file name or a --set string holds.
#pragma once

#include <nlohmann/json.hpp>

#include <string>

namespace cutsim {

// Two-space indented text with a final newline; bytes that are not UTF-8 become U+FFFD rather than
// an exception after the run (nlohmann's default throws type_error 316).
inline std::string jsonText(const nlohmann::json& j) {
    return j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

}  // namespace cutsim
