// One AVX-512 register of doubles as 8 lanes, one element per lane: the block kernels of the
// element forces (fem/forces.cpp) and of the per-element estimators (timestep/timestep.cpp) run
// the same fixed-size arithmetic on 8 elements at once (Eigen's fixed 3x3 and 12x12 code vectorises
// only within one element). GCC/Clang vector extensions; without AVX-512 they are split into
// narrower registers. Include only in .cpp files: the helpers have internal linkage, so GCC's note
// that a 64-byte vector return changes the ABI without AVX-512 concerns no call between objects.
#pragma once

#pragma GCC diagnostic ignored "-Wpsabi"

#if defined(__AVX512F__) && defined(__AVX512VL__)
#include <immintrin.h>
#endif

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
// Whether any lane of a comparison result is set (of Lane, or of the float lanes of fem/forces.cpp).
template <class Mask>
inline bool anyLane(const Mask& m) {
    bool any = false;
    for (unsigned l = 0; l < sizeof(Mask) / sizeof(m[0]); ++l) any = any || m[l];
    return any;
}

// kLanes consecutive doubles as one register (unaligned).
inline Lane loadLanes(const double* p) {
    Lane v;
    __builtin_memcpy(&v, p, sizeof v);
    return v;
}

#if defined(__AVX512F__) && defined(__AVX512VL__)
#define CUTSIM_LANE_TRANSPOSE 1
// out[r][l] = p[l][r] for r < 3: each 3-vector read by a masked 4-wide load (nothing read past
// its third double), then an 8x4 transpose in registers. One lane at a time, the same copy takes
// 24 scalar loads and stores and a wide reload of the stored lanes.
inline void transposeLanes3(const double* const p[kLanes], Lane out[3]) {
    __m512d z[4];
    for (int l = 0; l < 4; ++l)
        z[l] = _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_maskz_loadu_pd(0x7, p[l])),
                                  _mm256_maskz_loadu_pd(0x7, p[l + 4]), 1);
    // z[l] = [x_l y_l z_l 0 | x_l+4 y_l+4 z_l+4 0]; unpack pairs within 128-bit chunks
    const __m512d t0 = _mm512_unpacklo_pd(z[0], z[1]);  // [x0 x1 | z0 z1 | x4 x5 | z4 z5]
    const __m512d t1 = _mm512_unpackhi_pd(z[0], z[1]);  // [y0 y1 | 0 0 | y4 y5 | 0 0]
    const __m512d t2 = _mm512_unpacklo_pd(z[2], z[3]);  // [x2 x3 | z2 z3 | x6 x7 | z6 z7]
    const __m512d t3 = _mm512_unpackhi_pd(z[2], z[3]);  // [y2 y3 | 0 0 | y6 y7 | 0 0]
    const __m512i even = _mm512_setr_epi64(0, 1, 8, 9, 4, 5, 12, 13),
                  odd = _mm512_setr_epi64(2, 3, 10, 11, 6, 7, 14, 15);
    out[0] = (Lane)_mm512_permutex2var_pd(t0, even, t2);
    out[1] = (Lane)_mm512_permutex2var_pd(t1, even, t3);
    out[2] = (Lane)_mm512_permutex2var_pd(t0, odd, t2);
}

// The inverse: v[l] = [in[0][l] in[1][l] in[2][l] 0] for each lane l.
inline void untransposeLanes3(const Lane in[3], __m256d v[kLanes]) {
    const __m512d x = (__m512d)in[0], y = (__m512d)in[1], z = (__m512d)in[2], zero = _mm512_setzero_pd();
    const __m512d u0 = _mm512_unpacklo_pd(x, y);     // [x0 y0 | x2 y2 | x4 y4 | x6 y6]
    const __m512d u1 = _mm512_unpackhi_pd(x, y);     // [x1 y1 | x3 y3 | x5 y5 | x7 y7]
    const __m512d w0 = _mm512_unpacklo_pd(z, zero);  // [z0 0 | z2 0 | z4 0 | z6 0]
    const __m512d w1 = _mm512_unpackhi_pd(z, zero);  // [z1 0 | z3 0 | z5 0 | z7 0]
    const __m512i even = _mm512_setr_epi64(0, 1, 8, 9, 4, 5, 12, 13),
                  odd = _mm512_setr_epi64(2, 3, 10, 11, 6, 7, 14, 15);
    const __m512d r[4] = {_mm512_permutex2var_pd(u0, even, w0), _mm512_permutex2var_pd(u1, even, w1),
                          _mm512_permutex2var_pd(u0, odd, w0), _mm512_permutex2var_pd(u1, odd, w1)};
    for (int l = 0; l < 4; ++l) {  // r[l] = [lane l | lane l + 4]
        v[l] = _mm512_castpd512_pd256(r[l]);
        v[l + 4] = _mm512_extractf64x4_pd(r[l], 1);
    }
}
#endif

}  // namespace
}  // namespace cutsim
