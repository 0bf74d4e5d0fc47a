#include "cut/toughness.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>

namespace cutsim {

namespace {

// Gauss-Seidel sweeps of the front's projection (as contact/contact.hpp's) and its tolerance [m/s].
constexpr int kFrontSweeps = 32;
constexpr double kFrontSettled = 1e-9;

// The volume ratio below which an element at the front is crushed: the edge cuts there whatever
// the front's force. On a fine mesh the edge is a line load on ever smaller elements, which
// G = F / b alone would let it crush to inversion before the whole front pays G_c b; tissue under
// a sharp edge fails first (docs/method.md, "Tissue toughness").
constexpr double kCrushedVolume = 0.5;

// The front's account (docs/method.md, "Tissue toughness"): while the energy the blades' work
// left (less the stored, kinetic and damped energy) falls short of G_c times the area cut by D,
// the force cap rises by D / kDebtLength, so the debt is paid back over about that much of the
// edge's travel; by at most kDebtForce G_c b, a bound where the shortfall is not the front's
// (contact, crushing) or asks more force than the tissue under the edge bears.
constexpr double kDebtLength = 2e-3;  // [m]
constexpr double kDebtForce = 0.25;
constexpr long kAccountSteps = 4;

// Barycentric coordinates of p in the tet of nodes n at positions x; false for a flat tet.
bool frontBarycentric(const Eigen::Matrix3Xd& x, const int* n, const Eigen::Vector3d& p, Eigen::Vector4d& w) {
    Eigen::Matrix3d D;
    D << x.col(n[1]) - x.col(n[0]), x.col(n[2]) - x.col(n[0]), x.col(n[3]) - x.col(n[0]);
    const double det = D.determinant();
    if (!(std::abs(det) > 0)) return false;
    const Eigen::Vector3d l = D.inverse() * (p - x.col(n[0]));
    w << 1 - l.sum(), l.x(), l.y(), l.z();
    return true;
}

}  // namespace

const char* cutPhaseName(CutPhase p) {
    switch (p) {
    case CutPhase::Pressing: return "pressing";
    case CutPhase::Cutting: return "cutting";
    default: return "idle";
    }
}

BladeToughness::BladeToughness(double gc, int samples, double rate)
    : gc_(gc), samples_(std::max(2, samples)), sampleDt_(1.0 / rate) {}

void BladeToughness::endStroke() {
    points_.clear();
    frontRest_.clear();
    advanced_ = false;
    accountOpen_ = false;
    accountAge_ = 0;
    debt_ = 0;
    reaction_.setZero();
}

// Points along the edge, a hair ahead of it, in the element that holds each (the one it lies
// deepest in; cut pieces only when no whole element holds it). Returns how many were found and
// the largest distance behind the edge any of their elements reaches (reach).
int BladeToughness::seed(const Model& m, const Eigen::Matrix3Xd& x, const BladeEdge& edge, const Eigen::Vector3d& dir,
                         const std::vector<int>& candidates, const VirtualNodeTest& isVirtual, double* reach) {
    points_.clear();
    const Eigen::Vector3d ab = edge.b - edge.a;
    const double len = ab.norm();
    if (!(len > 0)) return 0;
    const double ahead = 1e-4 * len, step = 1.0 / samples_;
    const Eigen::Vector3d base = edge.a + ahead * dir;
    struct Best {
        int e = -1;
        double depth = -1;
        bool whole = false;
        Eigen::Vector4d w;
    };
    std::vector<Best> best(static_cast<size_t>(samples_));
    for (int e : candidates) {
        const int* n = m.tets.col(e).data();
        Eigen::Vector3d lo = x.col(n[0]), hi = lo;
        for (int k = 1; k < 4; ++k) lo = lo.cwiseMin(x.col(n[k])), hi = hi.cwiseMax(x.col(n[k]));
        // the samples whose parameter s in [0, 1] can lie in the element's box
        double s0 = 0, s1 = 1;
        for (int k = 0; k < 3 && s0 <= s1; ++k) {
            if (std::abs(ab[k]) < 1e-300) {
                if (base[k] < lo[k] || base[k] > hi[k]) s1 = -1;
                continue;
            }
            double t0 = (lo[k] - base[k]) / ab[k], t1 = (hi[k] - base[k]) / ab[k];
            if (t0 > t1) std::swap(t0, t1);
            s0 = std::max(s0, t0), s1 = std::min(s1, t1);
        }
        if (s0 > s1) continue;
        bool whole = true;
        for (int k = 0; k < 4 && whole; ++k)
            if (isVirtual(n[k])) whole = false;
        const int j0 = std::max(0, static_cast<int>(std::floor(s0 * samples_ - 0.5))),
                  j1 = std::min(samples_ - 1, static_cast<int>(std::ceil(s1 * samples_ - 0.5)));
        for (int j = j0; j <= j1; ++j) {
            Eigen::Vector4d w;
            if (!frontBarycentric(x, n, base + (j + 0.5) * step * ab, w)) continue;
            const double depth = w.minCoeff();
            if (depth < -1e-9) continue;
            Best& b = best[static_cast<size_t>(j)];
            if (b.e < 0 || (whole && !b.whole) || (whole == b.whole && depth > b.depth)) b = {e, depth, whole, w};
        }
    }
    // the rest coordinate along dir of each sample in the material (NaN: none)
    sampleRest_.assign(static_cast<size_t>(samples_), std::numeric_limits<double>::quiet_NaN());
    for (size_t j = 0; j < best.size(); ++j) {
        const Best& b = best[j];
        if (b.e < 0) continue;
        const int* n = m.tets.col(b.e).data();
        double r0 = 0;
        for (int k = 0; k < 4; ++k) r0 += b.w[k] * m.X.col(n[k]).dot(dir);
        sampleRest_[j] = r0;
    }
    // one point per element: the samples it holds, their weights averaged (points sharing an
    // element would be redundant constraints that Gauss-Seidel resolves slowly)
    double r = 0;
    for (const Best& b : best) {
        if (b.e < 0) continue;
        const int* n = m.tets.col(b.e).data();
        Point* p = nullptr;
        for (Point& q : points_)
            if (q.element == b.e) p = &q;
        if (!p) {
            points_.push_back({});
            p = &points_.back();
            p->element = b.e;
            for (int k = 0; k < 4; ++k) {
                p->node[static_cast<size_t>(k)] = n[k];
                r = std::max(r, (edge.a - x.col(n[k])).dot(dir));
            }
        }
        p->w += b.w;
        p->length += step * len;
    }
    for (Point& p : points_) p.w /= p.w.sum();
    if (reach) *reach = r;
    return static_cast<int>(points_.size());
}

// The crack grows by the front's advance in the rest configuration (G_c is per unit of crack area
// created, counted in the material): at each sample along the edge, how far the rest coordinate
// of the material at the front moved on since the sample last met it.
void BladeToughness::advanceRest(double sampleLength) {
    stepArea_ = 0;
    if (frontRest_.size() != sampleRest_.size()) frontRest_ = sampleRest_;
    for (size_t j = 0; j < sampleRest_.size(); ++j) {
        const double s = sampleRest_[j];
        if (std::isnan(s)) continue;
        double& f = frontRest_[j];
        if (!std::isnan(f) && s > f) stepArea_ += sampleLength * (s - f);
        if (std::isnan(f) || s > f) f = s;
    }
    area_ += stepArea_;
}

bool BladeToughness::sweepEdges(const Model& m, const Eigen::Matrix3Xd& x, const BladeEdge& now,
                                const Eigen::Vector3d& dir, const std::vector<int>& candidates,
                                const VirtualNodeTest& isVirtual, BladeEdge& from, BladeEdge& to) {
    if (advanced_) {
        advanced_ = false;
        from = front_, to = target_;
        front_ = target_;
        return true;
    }
    if (!points_.empty()) return false;
    double reach = 0;
    if (seed(m, x, now, dir, candidates, isVirtual, &reach) == 0) return false;
    frontRest_ = sampleRest_;
    // the first sweep starts behind the elements the edge entered (by its reach, and a margin)
    const Eigen::Vector3d back = (reach + 1e-3 * (now.b - now.a).norm()) * dir;
    front_ = {now.a - back, now.b - back};
    target_ = now;
    return false;
}

void BladeToughness::reseed(const Model& m, const Eigen::Matrix3Xd& x, const Eigen::Vector3d& dir,
                            const std::vector<int>& candidates, const VirtualNodeTest& isVirtual) {
    seed(m, x, front_, dir, candidates, isVirtual, nullptr);
    advanceRest((front_.b - front_.a).norm() / samples_);
}

void BladeToughness::project(const Model& m, double dt, const BladeEdge& edge, const Eigen::Vector3d& dir,
                             const std::function<double()>& stored, Eigen::Matrix3Xd& x, Eigen::Matrix3Xd& v) {
    const Eigen::VectorXd& invMass = m.invMass;
    reaction_.setZero();
    stepArea_ = 0;
    phase_ = points_.empty() ? CutPhase::Idle : CutPhase::Pressing;
    if (points_.empty() || !(dt > 0)) return;
    auto at = [](const Eigen::Matrix3Xd& y, const Point& p) {
        Eigen::Vector3d c = Eigen::Vector3d::Zero();
        for (int k = 0; k < 4; ++k) c += p.w[k] * y.col(p.node[static_cast<size_t>(k)]);
        return c;
    };
    auto apply = [&](Eigen::Matrix3Xd& y, const Point& p, double amount) {  // along dir, mass-weighted
        for (int k = 0; k < 4; ++k) {
            const int n = p.node[static_cast<size_t>(k)];
            y.col(n) += (amount * p.w[k] * invMass(n)) * dir;
        }
    };
    double length = 0, reached = 0;  // the front's length in the material, and where the edge reached it [m]
    bool crushed = false;            // an element the edge presses is crushed
    for (Point& p : points_) {
        double w2 = 0;
        for (int k = 0; k < 4; ++k) w2 += p.w[k] * p.w[k] * invMass(p.node[static_cast<size_t>(k)]);
        p.mass = w2 > 0 ? 1.0 / w2 : 0.0;
        p.pen = (edge.a - at(x, p)).dot(dir);  // how far the edge is past the point
        p.lambda = 0;
        p.push = 0;
        if (p.mass > 0) length += p.length;
        if (p.mass > 0 && p.pen > 0) reached += p.length;
        if (p.mass > 0 && p.pen > 0 && !crushed)  // the point's element and those around its nodes
            for (int k = 0; k < 4 && !crushed; ++k)
                for (int slot : m.slotsOf(p.node[static_cast<size_t>(k)])) {
                    const int e = slot / 4;
                    const int* n = m.tets.col(e).data();
                    Eigen::Matrix3d d;
                    d << x.col(n[1]) - x.col(n[0]), x.col(n[2]) - x.col(n[0]), x.col(n[3]) - x.col(n[0]);
                    if ((d * m.dmInv(e)).determinant() < kCrushedVolume) {
                        crushed = true;
                        break;
                    }
                }
    }
    dir_ = dir;
    if (!(reached > 0)) return;  // the edge has left the front (or not reached it): no force
    // velocities: a point may not fall back behind the edge, one ahead of it by a gap g only
    // by g / dt (held against the world, as contact holds, so a quasi-static edge moves what it
    // presses by positions)
    for (int it = 0; it < kFrontSweeps; ++it) {
        double change = 0;
        for (Point& p : points_) {
            if (!(p.mass > 0)) continue;
            const double allowed = p.pen < 0 ? p.pen / dt : 0.0;
            const double lambda = std::max(0.0, p.lambda + p.mass * (allowed - dir.dot(at(v, p))));
            apply(v, p, lambda - p.lambda);
            change = std::max(change, std::abs(lambda - p.lambda) / p.mass);
            p.lambda = lambda;
        }
        if (change <= kFrontSettled) break;
    }
    double total = 0;
    for (Point& p : points_) total += p.lambda;
    // impulse G_c b dt: the front's force at most G_c b (Griffith), more while the crack is in
    // debt D > 0: G_c b + D / l
    double cap = gc_ * length * dt;
    if (total > cap) {
        // the energy balance since the stroke's first rupture: the blades' work less the stored,
        // kinetic and damped energy and G_c times the area cut (a pass over the elements, so
        // every kAccountSteps such steps; the debt changes little over them)
        if (accountAge_++ % kAccountSteps == 0) {
            const double balance = work_ - damped_ - gc_ * area_ - stored();
            if (!accountOpen_) accountOpen_ = true, accountStart_ = balance;
            debt_ = accountStart_ - balance;
        }
        cap += std::clamp(debt_ / kDebtLength, 0.0, kDebtForce * gc_ * length) * dt;
    }
    if (total > cap || crushed) {
        // rupture or steady cutting: the capped impulse, the edge slides past the points, and the
        // area it slid over is cut (paid G_c each, or crushed)
        const double s = std::min(1.0, cap / total);
        crushedSteps_ += total <= cap;
        for (Point& p : points_) {
            if (!(p.lambda > 0)) continue;
            apply(v, p, (s - 1) * p.lambda);
            p.lambda *= s;
            apply(x, p, dt * p.lambda);  // and the position by what that velocity moves it in a step
        }
        phase_ = CutPhase::Cutting;
        target_ = edge;
        advanced_ = true;
        reaction_ = -(std::min(cap, total) / dt) * dir;
        return;
    }
    // pressing: the points move with the edge (depths linearised about where the step left them)
    for (Point& p : points_) p.c0 = dir.dot(at(x, p));
    for (int it = 0; it < kFrontSweeps; ++it) {
        double change = 0;
        for (Point& p : points_) {
            if (!(p.mass > 0 && p.pen > 0)) continue;
            const double depth = p.pen - (dir.dot(at(x, p)) - p.c0);
            const double push = std::max(0.0, p.push + p.mass * depth);
            apply(x, p, push - p.push);
            change = std::max(change, std::abs(push - p.push) / p.mass);
            p.push = push;
        }
        if (change <= 1e-12) break;
    }
    reaction_ = -(total / dt) * dir;
}

CutPhase BladeToughness::phaseOver(double now, double window) const {
    for (auto it = segments_.rbegin(); it != segments_.rend() && it->end > now - window; ++it)
        if (it->phase == CutPhase::Cutting) return CutPhase::Cutting;
    return phase_;
}

void BladeToughness::record(double t, double dt, long step, double work, double along, double damped) {
    work_ += work;
    damped_ += damped;
    peak_ = std::max(peak_, along);
    pressingSteps_ += phase_ == CutPhase::Pressing;
    cuttingSteps_ += phase_ == CutPhase::Cutting;
    if (segments_.empty() || segments_.back().phase != phase_)
        segments_.push_back({phase_, step, step, t, t + dt});
    else
        segments_.back().last = step, segments_.back().end = t + dt;
    impulse_ += along * dt;
    window_ += dt;
    if (t >= nextSample_ - 1e-12) {
        sTime_.push_back(t);
        sForce_.push_back(window_ > 0 ? impulse_ / window_ : along);
        sArea_.push_back(area_);
        sPhase_.push_back(static_cast<int>(phase_));
        impulse_ = window_ = 0;
        nextSample_ += sampleDt_;
    }
}

nlohmann::json BladeToughness::report(double elastic0, double kinetic0, double gravity0, double elastic, double kinetic,
                                      double gravity) const {
    using json = nlohmann::json;
    json segs = json::array();
    for (const Segment& s : segments_)
        segs.push_back({{"phase", cutPhaseName(s.phase)},
                        {"first_step", s.first},
                        {"last_step", s.last},
                        {"start", s.start},
                        {"end", s.end}});
    json phases = json::array();
    for (int p : sPhase_) phases.push_back(cutPhaseName(static_cast<CutPhase>(p)));
    const double dE = elastic - elastic0, dK = kinetic - kinetic0, dG = gravity - gravity0;
    const double accounted = dE + dK + dG + fracture() + damped_;
    return {{"toughness", gc_},
            {"cut_area", area_},
            {"peak_force", peak_},
            {"pressing_steps", pressingSteps_},
            {"cutting_steps", cuttingSteps_},
            {"crushed_steps", crushedSteps_},
            {"phases", segs},
            {"energy",
             {{"work", work_},
              {"elastic", dE},
              {"kinetic", dK},
              {"gravity", dG},
              {"fracture", fracture()},
              {"damping", damped_},
              {"residual", work_ - accounted}}},
            {"series", {{"time", sTime_}, {"force", sForce_}, {"cut_area", sArea_}, {"phase", phases}}}};
}

}  // namespace cutsim
