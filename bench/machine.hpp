// The machine a benchmark ran on, recorded in its JSON result: results are committed per machine,
// and every time in them is a wall time on a machine other work may share.
#pragma once

#include <nlohmann/json_fwd.hpp>

namespace cutsim {

// {cpu, cores, load_average: [1, 5, 15 min]} now.
nlohmann::json machineJson();
// The 1, 5 and 15 minute load averages now (empty where the system gives none).
nlohmann::json loadAverage();

}  // namespace cutsim
