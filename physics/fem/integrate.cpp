#include "fem/integrate.hpp"

#include "fem/forces.hpp"
#include "fem/kinematics.hpp"
#include "fem/tet.hpp"

#include <Eigen/Geometry>
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace cutsim {

// Node loops are light: only worth threads on large meshes.
constexpr int kParallelNodes = 16384;

Integrator parseIntegrator(const std::string& name) {
    if (name == "symplectic_euler") return Integrator::SymplecticEuler;
    if (name == "central_difference") return Integrator::CentralDifference;
    if (name == "newmark") return Integrator::Newmark;
    if (name == "backward_euler") return Integrator::BackwardEuler;
    throw InputError("unknown integrator '" + name +
                     "' (symplectic_euler, central_difference, newmark, backward_euler)");
}

const char* integratorName(Integrator i) {
    switch (i) {
    case Integrator::SymplecticEuler: return "symplectic_euler";
    case Integrator::CentralDifference: return "central_difference";
    case Integrator::Newmark: return "newmark";
    case Integrator::BackwardEuler: return "backward_euler";
    }
    return "?";
}

ImplicitSolver parseImplicitSolver(const std::string& name) {
    if (name == "direct") return ImplicitSolver::Direct;
    if (name == "cg") return ImplicitSolver::ConjugateGradient;
    throw InputError("unknown implicit solver '" + name + "' (direct, cg)");
}

const char* implicitSolverName(ImplicitSolver s) { return s == ImplicitSolver::Direct ? "direct" : "cg"; }

Eigen::VectorXd elementAlpha(const Eigen::VectorXd& dtCritElem, double dt) {
    Eigen::VectorXd a(dtCritElem.size());
    for (Eigen::Index e = 0; e < a.size(); ++e) {
        const double r = dtCritElem(e) / dt;
        a(e) = r >= 1 ? 1.0 : r * r;  // thesis eq. 3.16: damp only elements faster than dt
    }
    return a;
}

// Backward Euler, linearised about the current rotations (Baraff & Witkin 1998 with the
// corotational tangent R K R^T): (M (1 + c dt) + dt^2 K_R) v+ = M v + dt f(x), x+ = x + dt v+.
struct ImplicitWorkspace {
    std::vector<int> dofMap;        // global DOF -> free DOF, or -1 (3 nNodes)
    Eigen::SparseMatrix<double> A;  // system matrix on free DOFs
    std::vector<int> slot;          // per element 144 entries -> index in A.valuePtr(), -1 if fixed
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
    // Lower|Upper: Eigen runs the product with the full matrix, on all threads
    Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> cg;
    bool analysed = false;  // solver's ordering and pattern, made on first use
    int iterations = 0;     // CG iterations of the last step
    int nElems = -1, nNodes = -1;

    void build(const Model& m) {
        nElems = m.elements();
        nNodes = m.nodes();
        dofMap.assign(3 * nNodes, -1);
        int nf = 0;
        for (int i = 0; i < nNodes; ++i)
            if (m.invMass(i) > 0)
                for (int k = 0; k < 3; ++k) dofMap[3 * i + k] = nf++;
        std::vector<Eigen::Triplet<double>> trips;
        for (int i = 0; i < nf; ++i) trips.emplace_back(i, i, 0.0);
        for (int e = 0; e < nElems; ++e)
            for (int r = 0; r < 12; ++r)
                for (int c = 0; c < 12; ++c) {
                    const int gi = dofMap[3 * m.tets(r / 3, e) + r % 3], gj = dofMap[3 * m.tets(c / 3, e) + c % 3];
                    if (gi >= 0 && gj >= 0) trips.emplace_back(gi, gj, 0.0);
                }
        A.resize(nf, nf);
        A.setFromTriplets(trips.begin(), trips.end());
        A.makeCompressed();
        slot.assign(static_cast<size_t>(nElems) * 144, -1);
        for (int e = 0; e < nElems; ++e)
            for (int r = 0; r < 12; ++r)
                for (int c = 0; c < 12; ++c) {
                    const int gi = dofMap[3 * m.tets(r / 3, e) + r % 3], gj = dofMap[3 * m.tets(c / 3, e) + c % 3];
                    if (gi < 0 || gj < 0) continue;
                    // column-major: find row gi in column gj
                    const int* rows = A.innerIndexPtr();
                    int lo = A.outerIndexPtr()[gj], hi = A.outerIndexPtr()[gj + 1];
                    const int* p = std::lower_bound(rows + lo, rows + hi, gi);
                    slot[static_cast<size_t>(e) * 144 + r * 12 + c] = static_cast<int>(p - rows);
                }
        analysed = false;
    }

    void step(const Model& m, State& s, const StepOptions& opt) {
        const double dt = opt.dt;
        if (nElems != m.elements() || nNodes != m.nodes()) build(m);
        // s.f and s.rot come from the force stage the caller just ran
        const double c = m.massDamping;
        double* val = A.valuePtr();
        std::fill(val, val + A.nonZeros(), 0.0);
        for (int i = 0; i < nNodes; ++i)
            for (int k = 0; k < 3; ++k) {
                const int d = dofMap[3 * i + k];
                if (d >= 0) A.coeffRef(d, d) += m.mass(i) * (1 + c * dt);
            }
        const bool corot = m.elementModel == ElementModel::Corotational;
        for (int e = 0; e < nElems; ++e) {
            Mat12 K = elementStiffness(shapeGradients(m.dmInv(e)), m.stiffnessVolume(e), m.material);
            if (corot) {
                const Eigen::Map<const Eigen::Matrix3d> R(s.rot.col(e).data());
                for (int a = 0; a < 4; ++a)
                    for (int b = 0; b < 4; ++b)
                        K.block<3, 3>(3 * a, 3 * b) = R * K.block<3, 3>(3 * a, 3 * b) * R.transpose();
            }
            const int* sl = &slot[static_cast<size_t>(e) * 144];
            for (int r = 0; r < 12; ++r)
                for (int cc = 0; cc < 12; ++cc)
                    if (sl[r * 12 + cc] >= 0) val[sl[r * 12 + cc]] += dt * dt * K(r, cc);
        }
        Eigen::VectorXd rhs(A.rows());
        for (int i = 0; i < nNodes; ++i)
            for (int k = 0; k < 3; ++k) {
                const int d = dofMap[3 * i + k];
                if (d >= 0) rhs(d) = m.mass(i) * s.v(k, i) + dt * s.f(k, i);
            }
        Eigen::VectorXd vNew;
        iterations = 0;
        if (opt.solver == ImplicitSolver::Direct) {
            if (!analysed) {
                solver.analyzePattern(A);
                analysed = true;
            }
            solver.factorize(A);
            if (solver.info() != Eigen::Success) throw std::runtime_error("backward Euler: factorisation failed");
            vNew = solver.solve(rhs);
        } else if (!rhs.allFinite()) {
            // CG would iterate to its cap on NaNs; pass them on for checkFinite to flag
            vNew = rhs;
        } else {
            // A is SPD (M > 0 on free DOFs, K_R semi-definite); v+ differs from v by dt a.
            Eigen::VectorXd guess(A.rows());
            for (int i = 0; i < nNodes; ++i)
                for (int k = 0; k < 3; ++k)
                    if (dofMap[3 * i + k] >= 0) guess(dofMap[3 * i + k]) = s.v(k, i);
            cg.setTolerance(opt.cgTolerance);
            cg.setMaxIterations(std::max<Eigen::Index>(1000, 10 * A.rows()));
            cg.compute(A);
            vNew = cg.solveWithGuess(rhs, guess);
            iterations = static_cast<int>(cg.iterations());
            if (cg.info() != Eigen::Success)
                throw std::runtime_error("backward Euler: CG did not reach its tolerance in " +
                                         std::to_string(iterations) + " iterations");
        }
        for (int i = 0; i < nNodes; ++i)
            for (int k = 0; k < 3; ++k) {
                const int d = dofMap[3 * i + k];
                s.v(k, i) = d >= 0 ? vNew(d) : 0.0;
            }
        s.x += dt * s.v;
    }
};

Stepper::Stepper() = default;
Stepper::~Stepper() = default;
Stepper::Stepper(Stepper&&) noexcept = default;
Stepper& Stepper::operator=(Stepper&&) noexcept = default;
void Stepper::reset() { implicit_.reset(); }
int Stepper::lastSolverIterations() const { return implicit_ ? implicit_->iterations : 0; }

void checkFinite(const Model& m, State& s) {
    int bad = 0;
    for (int i = 0; i < m.nodes(); ++i) bad += nonFiniteNode(s, i);
    s.flags.nonFinite = bad;
}

void Stepper::forces(const Model& m, State& s, const double* alpha, double watch, bool allRotations,
                     NodeUpdate* update) {
    const auto t0 = std::chrono::steady_clock::now();
    ForceStageSeconds times;
    computeForces(m, s, alpha, watch, allRotations, update ? &times : nullptr, update);
    // the update's share (first thread's clock) counts as integration
    forceSeconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() - times.update;
}

// Calls f(o) for each node o sharing an element with n, once per shared element. Prescribed
// neighbours count (at rest): a copy hanging at the clamp is damped towards it.
template <class F>
void forNeighbours(const Model& m, int n, F&& f) {
    for (int sl = m.nodeSlotStart[n]; sl < m.nodeSlotEnd[n]; ++sl) {
        const int e = m.nodeSlots[static_cast<size_t>(sl)] / 4;
        for (int a = 0; a < 4; ++a) {
            const int o = m.tets(a, e);
            if (o != n) f(o);
        }
    }
}

// A light control point rings against its element at that element's top frequency with a mass
// share of a few percent; at large stretch the corotational tangent then outgrows the step (bar
// run 57 of `cutsim bench stability`: 2.3e-6 kg on an element of share 0.056, stretches up to 4.5,
// blown up 125 steps after the cut). Its velocity relative to the mass-weighted mean vbar of the
// nodes it shares elements with (at the start of the step) is damped with c = 0.5 / dt, taken
// implicitly like the mass damping: v = (v_plain + c dt vbar) / (1 + c dt), and the position
// update follows. (Applied after the position update, such damping lowers the node's stable
// step instead: to sqrt(3)/2 of the limit at c dt = 1.) A rigid motion with the neighbours is
// kept. Measured on the random cuts: c dt = 1/2 and 1 both remove every blow-up; momentum is
// not passed on to the neighbours (doing so explicitly brought blow-ups back), so the momentum
// changed is that of nodes of a few percent of the mass.
constexpr double kLightDamping = 0.5;  // c dt [-]
void Stepper::lightMeans(const Model& m, const State& s) {
    lightMean_.resize(3, static_cast<Eigen::Index>(m.lightNodes.size()));
    for (size_t k = 0; k < m.lightNodes.size(); ++k) {
        const int n = m.lightNodes[k];
        Eigen::Vector3d mv = Eigen::Vector3d::Zero();
        double mass = 0;
        forNeighbours(m, n, [&](int o) {
            mv += m.mass(o) * s.v.col(o);
            mass += m.mass(o);
        });
        lightMean_.col(static_cast<Eigen::Index>(k)) =
            mass > 0 ? Eigen::Vector3d(mv / mass) : Eigen::Vector3d(s.v.col(n));
    }
}

void Stepper::dampLight(const Model& m, State& s, double dt) const {
    for (size_t k = 0; k < m.lightNodes.size(); ++k) {
        const int n = m.lightNodes[k];
        if (m.invMass(n) == 0) continue;
        const Eigen::Vector3d dv =
            kLightDamping / (1 + kLightDamping) * (lightMean_.col(static_cast<Eigen::Index>(k)) - s.v.col(n));
        s.v.col(n) += dv;
        s.x.col(n) += dt * dv;
    }
}

const double* Stepper::forceFactors(const Model& m, const double* alpha) {
    if (m.matchedList.empty()) return alpha;
    matchAlpha_.resize(m.elements());
    if (alpha)
        matchAlpha_ = Eigen::Map<const Eigen::VectorXd>(alpha, m.elements());
    else
        matchAlpha_.setOnes();
    for (const int e : m.matchedList) matchAlpha_(e) = 0;  // moved by shape matching, not by forces
    return matchAlpha_.data();
}

// The stretch bound of partial elements, or 0 when none is held apart (StepOptions::holdPartial).
double Stepper::partialStretch(const Model& m, const StepOptions& opt) const {
    if (!opt.holdPartial || !(opt.minStretch > 0) || !(opt.minStretch < kPartialMinStretch)) return 0;
    return anyPartial(m) ? kPartialMinStretch : 0;
}

void Stepper::limit(const Model& m, State& s, const StepOptions& opt, int nearFlat) {
    if (opt.minStretch > 0 && nearFlat > 0)
        s.flags.limited = limitStretch(m, s, opt.minStretch, limitScratch_, partialStretch(m, opt));
}

int Stepper::repairInverted(const Model& m, State& s, const StepOptions& opt, const std::vector<int>& nodes) {
    if (!(opt.minStretch > 0) || nodes.empty()) return 0;
    repairSeeds_.clear();
    for (const int i : nodes) {
        for (int k = m.nodeSlotStart[i]; k < m.nodeSlotEnd[i]; ++k) {
            const int e = m.nodeSlots[k] >> 2;
            if (!(deformationGradient(m, s, e).determinant() > 0)) repairSeeds_.push_back(e);
        }
    }
    if (repairSeeds_.empty()) return 0;
    std::sort(repairSeeds_.begin(), repairSeeds_.end());
    repairSeeds_.erase(std::unique(repairSeeds_.begin(), repairSeeds_.end()), repairSeeds_.end());
    return limitStretch(m, s, opt.minStretch, limitScratch_, partialStretch(m, opt), &repairSeeds_);
}

void Stepper::step(const Model& m, State& s, const StepOptions& opt) {
    forceSeconds_ = 0;
    const double dt = opt.dt, c = m.massDamping;
    const double* alpha = forceFactors(m, opt.alphaElem ? opt.alphaElem->data() : nullptr);
    const double watch =
        opt.minStretch > 0 ? std::max(opt.minStretch, partialStretch(m, opt)) + kStretchWatchMargin : 0;
    const int n = m.nodes();
    const int nearBefore = s.flags.nearFlat;  // Newmark moves before its force stage
    s.flags = {};
    switch (opt.integrator) {
    case Integrator::SymplecticEuler: {
        if (!m.lightNodes.empty()) lightMeans(m, s);
        // damping taken implicitly so it never limits the step: v = (v + dt a) / (1 + c dt);
        // the update runs in the force stage's parallel region
        NodeUpdate up{1.0, dt, 1.0 / (1.0 + c * dt), dt};
        forces(m, s, alpha, watch, false, &up);
        s.flags.nonFinite = up.nonFinite;
        if (!m.lightNodes.empty()) dampLight(m, s, dt);
        shapeMatch(m, s, dt, match_);
        limit(m, s, opt, s.flags.nearFlat);
        break;
    }
    case Integrator::CentralDifference: {
        // v_{n+1/2} = ((1 - c dt/2) v_{n-1/2} + dt a_n) / (1 + c dt/2); the first step is a half step.
        if (!m.lightNodes.empty()) lightMeans(m, s);
        const double h = s.started ? dt : 0.5 * dt;
        NodeUpdate up{1.0 - 0.5 * c * h, h, 1.0 / (1.0 + 0.5 * c * h), dt};
        forces(m, s, alpha, watch, false, &up);
        s.flags.nonFinite = up.nonFinite;
        if (!m.lightNodes.empty()) dampLight(m, s, dt);
        shapeMatch(m, s, dt, match_);
        s.started = true;
        limit(m, s, opt, s.flags.nearFlat);
        break;
    }
    case Integrator::Newmark: {
        // Explicit Newmark (beta = 0, gamma = 1/2) with the damping factor alpha on the
        // acceleration (thesis eqs. 3.11-3.12); mass damping centred like the velocity update.
        if (!s.started) {
            forces(m, s, alpha, watch);
            for (int i = 0; i < n; ++i) s.a.col(i) = m.invMass(i) * s.f.col(i);
            s.started = true;
        }
        const double al = opt.alpha;
#pragma omp parallel for schedule(static) if (n >= kParallelNodes)
        for (int i = 0; i < n; ++i) {
            if (m.invMass(i) == 0) continue;
            s.x.col(i) += dt * s.v.col(i) + 0.5 * dt * dt * al * (s.a.col(i) - c * s.v.col(i));
        }
        limit(m, s, opt, nearBefore);
        forces(m, s, alpha, watch);
        const double cm = 1.0 - 0.5 * c * dt, cp = 1.0 / (1.0 + 0.5 * c * dt);
#pragma omp parallel for schedule(static) if (n >= kParallelNodes)
        for (int i = 0; i < n; ++i) {
            const double w = m.invMass(i);
            if (w == 0) {
                s.v.col(i).setZero();
                s.a.col(i).setZero();
                continue;
            }
            const Eigen::Vector3d aNew = w * s.f.col(i);
            s.v.col(i) = (cm * s.v.col(i) + 0.5 * dt * al * (s.a.col(i) + aNew)) * cp;
            s.a.col(i) = aNew;
        }
        shapeMatch(m, s, dt, match_);
        break;
    }
    case Integrator::BackwardEuler: {
        if (!implicit_) implicit_ = std::make_unique<ImplicitWorkspace>();
        // the tangent is assembled from every element's R; no damping factors (matched elements: none)
        forces(m, s, forceFactors(m, nullptr), watch, true);
        implicit_->step(m, s, opt);
        shapeMatch(m, s, dt, match_);
        limit(m, s, opt, s.flags.nearFlat);
        break;
    }
    }
    s.time += dt;
    ++s.steps;
    // Symplectic Euler and central difference count non-finite nodes in their update pass; a
    // second pass over every node is needed only where nodes moved after it (light-node damping,
    // stretch limiting).
    const bool counted =
        opt.integrator == Integrator::SymplecticEuler || opt.integrator == Integrator::CentralDifference;
    if (!counted || !m.lightNodes.empty() || !m.matchedList.empty() || s.flags.limited > 0) checkFinite(m, s);
}

}  // namespace cutsim
