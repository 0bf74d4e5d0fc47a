// One AVX-512 register of doubles as 8 lanes, one element per lane: the block kernels of the
// element forces (fem/forces.cpp) and of the per-element estimators (timestep/timestep.cpp) run
// the same fixed-size arithmetic on 8 elements at once (Eigen's fixed 3x3 and 12x12 code vectorises
// only within one element). GCC/Clang vector extensions; without AVX-512 they are split into
// narrower registers. Include only in .cpp files: the helpers have internal linkage, so GCC's note
// that a 64-byte vector return changes the ABI without AVX-512 concerns no call between objects.
#pragma once

#pragma GCC diagnostic ignored "-Wpsabi"

namespace cutsim {
namespace {

constexpr int kLanes = 8;
typedef double Lane __attribute__((vector_size(8 * kLanes)));
typedef long LaneMask __attribute__((vector_size(8 * kLanes)));  // comparison result: -1 true, 0 false

inline Lane sqrtLanes(Lane x) {
    for (int l = 0; l < kLanes; ++l) x[l] = __builtin_sqrt(x[l]);
    return x;
}
inline Lane absLanes(Lane x) { return x < 0 ? -x : x; }
inline bool anyLane(LaneMask m) {
    bool any = false;
    for (int l = 0; l < kLanes; ++l) any = any || m[l];
    return any;
}

} // namespace
} // namespace cutsim
