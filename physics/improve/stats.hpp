// What improve.cpp shares with stats.cpp.
#pragma once

#include "improve/improve.hpp"

namespace cutsim {

// meshStepStats with the exact step already known (dtExact > 0: the Lanczos solve is skipped).
MeshStepStats stepStats(const TetMesh& mesh, const Material& material, double dtExact);

}  // namespace cutsim
