// A mode's oscillation, measured from a sampled signal and predicted for an integrator: how the
// accuracy bench tells an integrator's damping and period error from the mesh's own error.
#pragma once

#include "fem/integrate.hpp"

#include <complex>
#include <vector>

namespace cutsim {

// The dominant oscillation of a sampled signal y(t), a least-squares fit of
// c + exp(-decay t) (a cos(2 pi f t) + b sin(2 pi f t)) (Levenberg-Marquardt). It starts from the
// frequency of the upward crossings of the mean and the decay of a line through ln |extreme - mean|
// of each half cycle; those alone are biased for a decaying signal, whose mean is off its centre.
struct Oscillation {
    double frequency = 0;  // [Hz]; 0 with fewer than two upward crossings
    double decay = 0;      // [1/s], positive when the amplitude falls; 0 with fewer than two half cycles
    int halfCycles = 0;    // half cycles seen; the fit needs two
};
Oscillation fitOscillation(const std::vector<double>& t, const std::vector<double>& y);

// An undamped mode of angular frequency w stepped by an integrator at dt, as the complex frequency
// s = ln(z) / dt of its amplification z per step (the mode goes as exp(s t)):
// - symplectic Euler: |z| = 1 and arg z = 2 asin(w dt / 2) (stable while w dt <= 2);
// - backward Euler: z = 1 / (1 + i w dt), so it decays at ln(1 + w^2 dt^2) / (2 dt) and turns at
//   atan(w dt) / dt (Hairer & Wanner, stability function 1 / (1 - z) on z = i w dt).
// Other integrators throw std::invalid_argument.
std::complex<double> integratorMode(Integrator integrator, double w, double dt);

// Relative error of a mode's complex frequency against an undamped reference: |s - i wRef| / wRef.
// It sees a period error and a decay alike: a damping ratio of 1% alone is an error of 1%.
double modeError(std::complex<double> s, double wRef);

// The largest dt at which backward Euler on a mode w has modeError at most target against wRef;
// 0 when the mode alone (the mesh's error) is already target or more off.
double backwardEulerDtForError(double w, double wRef, double target);

}  // namespace cutsim
