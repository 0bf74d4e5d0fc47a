// The box the step benchmarks share (`cutsim bench step`, the step and Bullet benchmark programs),
// so that their tet-steps per second are of the same model.
#pragma once

#include "fem/model.hpp"

namespace cutsim {

// n^3 cubes of 1 cm (6 n^3 tets) of the default material, clamped at x = 0, gravity -z.
Model stepBox(int n);

}  // namespace cutsim
