// Measured and predicted oscillation of a mode (see oscillation.hpp).
#include "bench/oscillation.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace cutsim {

namespace {

// Times at which y crosses level upwards (upOnly) or either way, by linear interpolation.
std::vector<double> crossings(const std::vector<double>& t, const std::vector<double>& y, double level, bool upOnly) {
    std::vector<double> c;
    for (size_t k = 1; k < y.size(); ++k) {
        const bool up = y[k - 1] < level && y[k] >= level, down = y[k - 1] >= level && y[k] < level;
        if (up || (!upOnly && down)) c.push_back(t[k - 1] + (level - y[k - 1]) / (y[k] - y[k - 1]) * (t[k] - t[k - 1]));
    }
    return c;
}

// Least squares of y ~ c + exp(-sigma tau) (a cos(w tau) + b sin(w tau)), tau = t - t_mid, by
// Levenberg-Marquardt on all five parameters from the crossing and peak estimates. Crossings of a
// decaying signal are biased: its mean over whole periods is not its centre, and a level off the
// centre shifts the crossings more as the amplitude falls (0.4% low at a 5% damping ratio).
void refine(const std::vector<double>& t, const std::vector<double>& y, Oscillation& r) {
    const size_t n = t.size();
    const double tMid = 0.5 * (t.front() + t.back());
    Eigen::Matrix<double, 5, 1> p;  // c, a, b, sigma, w
    p << 0, 0, 0, r.decay, 2 * M_PI * r.frequency;
    // c, a, b for the starting sigma and w: linear least squares
    {
        Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
        Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
        for (size_t k = 0; k < n; ++k) {
            const double tau = t[k] - tMid, e = std::exp(-p(3) * tau);
            const Eigen::Vector3d g(1, e * std::cos(p(4) * tau), e * std::sin(p(4) * tau));
            A += g * g.transpose();
            rhs += g * y[k];
        }
        p.head<3>() = A.ldlt().solve(rhs);
    }
    auto cost = [&](const Eigen::Matrix<double, 5, 1>& q, Eigen::Matrix<double, 5, 5>* JtJ,
                    Eigen::Matrix<double, 5, 1>* Jtr) {
        double sum = 0;
        JtJ->setZero();
        Jtr->setZero();
        for (size_t k = 0; k < n; ++k) {
            const double tau = t[k] - tMid, e = std::exp(-q(3) * tau), c = std::cos(q(4) * tau),
                         s = std::sin(q(4) * tau);
            const double osc = e * (q(1) * c + q(2) * s), res = y[k] - q(0) - osc;
            sum += res * res;
            Eigen::Matrix<double, 5, 1> g;
            g << 1, e * c, e * s, -tau * osc, tau * e * (q(2) * c - q(1) * s);
            *JtJ += g * g.transpose();
            *Jtr += g * res;
        }
        return sum;
    };
    Eigen::Matrix<double, 5, 5> JtJ, JtJq;
    Eigen::Matrix<double, 5, 1> Jtr, Jtrq;
    double f = cost(p, &JtJ, &Jtr), lambda = 1e-3;
    for (int it = 0; it < 100 && std::isfinite(f); ++it) {
        Eigen::Matrix<double, 5, 5> H = JtJ;
        H.diagonal() *= 1 + lambda;
        const Eigen::Matrix<double, 5, 1> step = H.ldlt().solve(Jtr), q = p + step;
        const double fq = cost(q, &JtJq, &Jtrq);  // with its Jacobian: one pass per trial
        if (std::isfinite(fq) && fq <= f) {
            const bool done = std::abs(step(4)) < 1e-12 * std::abs(q(4)) && std::abs(step(3)) < 1e-12 * std::abs(q(4));
            p = q;
            f = fq;
            JtJ = JtJq;
            Jtr = Jtrq;
            lambda = std::max(lambda / 10, 1e-12);
            if (done) break;
        } else {
            lambda *= 10;
            if (lambda > 1e12) break;
        }
    }
    if (std::isfinite(p(3)) && std::isfinite(p(4)) && p(4) > 0) {
        r.decay = p(3);
        r.frequency = p(4) / (2 * M_PI);
    }
}

}  // namespace

Oscillation fitOscillation(const std::vector<double>& t, const std::vector<double>& y) {
    Oscillation r;
    if (y.size() < 3) return r;
    double mean = 0;
    for (double v : y) mean += v;
    mean /= static_cast<double>(y.size());
    std::vector<double> up = crossings(t, y, mean, true);
    // The mean of a window that is not a whole number of periods is off; re-centre on the mean
    // between the first and the last crossing, then count again.
    if (up.size() >= 2) {
        double s = 0, w = 0;
        for (size_t k = 1; k < y.size(); ++k)
            if (t[k] > up.front() && t[k] <= up.back()) {
                s += y[k] * (t[k] - t[k - 1]);
                w += t[k] - t[k - 1];
            }
        if (w > 0) mean = s / w;
        up = crossings(t, y, mean, true);
    }
    if (up.size() < 2) return r;
    r.frequency = static_cast<double>(up.size() - 1) / (up.back() - up.front());
    // Decay: the largest |y - mean| between consecutive crossings (a half cycle), then a
    // least-squares line through (time of that extreme, ln of it).
    const std::vector<double> both = crossings(t, y, mean, false);
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    size_t k = 0;
    for (size_t c = 1; c < both.size(); ++c) {
        double amp = 0, at = 0;
        for (; k < y.size() && t[k] < both[c]; ++k)
            if (t[k] > both[c - 1] && std::abs(y[k] - mean) > amp) {
                amp = std::abs(y[k] - mean);
                at = t[k];
            }
        if (amp <= 0) continue;
        const double ly = std::log(amp);
        sx += at;
        sy += ly;
        sxx += at * at;
        sxy += at * ly;
        ++r.halfCycles;
    }
    const double n = r.halfCycles, det = n * sxx - sx * sx;
    if (r.halfCycles >= 2 && det > 0) r.decay = -(n * sxy - sx * sy) / det;
    if (r.halfCycles >= 2) refine(t, y, r);
    return r;
}

std::complex<double> integratorMode(Integrator integrator, double w, double dt) {
    const double u = w * dt;
    switch (integrator) {
    case Integrator::SymplecticEuler: return {0.0, 2 * std::asin(std::min(1.0, u / 2)) / dt};
    case Integrator::BackwardEuler: return {-std::log1p(u * u) / (2 * dt), std::atan(u) / dt};
    default: throw std::invalid_argument("integratorMode: symplectic_euler or backward_euler");
    }
}

double modeError(std::complex<double> s, double wRef) { return std::abs(s - std::complex<double>(0, wRef)) / wRef; }

double backwardEulerDtForError(double w, double wRef, double target) {
    if (!(std::abs(w - wRef) / wRef < target)) return 0;
    // The error grows with dt (the decay, ~ w dt / 2, outgrows the period's shortfall); bisect on
    // a log scale between a dt that meets the target and one that does not.
    double lo = 1e-6 / w, hi = 10 / w;
    auto err = [&](double dt) { return modeError(integratorMode(Integrator::BackwardEuler, w, dt), wRef); };
    if (err(lo) > target) return 0;
    for (int it = 0; it < 200 && hi / lo > 1 + 1e-12; ++it) {
        const double mid = std::sqrt(lo * hi);
        (err(mid) <= target ? lo : hi) = mid;
    }
    return lo;
}

}  // namespace cutsim
