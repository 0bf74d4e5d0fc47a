// What improve.cpp shares with stats.cpp.
#pragma once

#include "improve/improve.hpp"

namespace cutsim {

// meshStepStats with the exact step already known (dtExact > 0: the Lanczos solve is skipped).
MeshStepStats stepStats(const TetMesh& mesh, const Material& material, double dtExact);
// The counts and volume of a mesh whose smallest R1R step is known, without the other steps.
MeshStepStats r1rStats(const TetMesh& mesh, double dtR1R);

}  // namespace cutsim
