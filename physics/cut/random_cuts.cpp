#include "cut/random_cuts.hpp"

#include "fem/integrate.hpp"
#include "mesh/generate.hpp"
#include "timestep/analyzer.hpp"

#include <algorithm>
#include <cmath>
#include <random>

namespace cutsim {

Model randomCutLiverModel(const TetMesh& liverInches) {
    TetMesh mesh = liverInches;
    mesh.X *= 0.0254;
    Model m = buildModel(mesh, Material{});
    m.gravity = Eigen::Vector3d(0, -9.81, 0);
    for (int i = 0; i < m.nodes(); ++i) m.fixed[i] = m.X(2, i) < -0.028;
    m.massDamping = 5;
    updateMasses(m);
    return m;
}

Model randomCutBarModel() {
    Model m = buildModel(boxMesh(0.1, 0.02, 0.02, 10, 2, 2), Material{});
    m.gravity = Eigen::Vector3d(0, 0, -9.81);
    for (int i = 0; i < m.nodes(); ++i) m.fixed[i] = m.X(0, i) < 1e-9;
    m.massDamping = 5;
    updateMasses(m);
    return m;
}

RandomCutStats runRandomCuts(const Model& base, int runs, int stepsBetween, unsigned seed, MassLumping lumping,
                             double dtFactor) {
    RandomCutStats st;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> uni(0, 1);
    const Eigen::Vector3d lo = base.X.rowwise().minCoeff(), hi = base.X.rowwise().maxCoeff();
    const double dt0 = TimestepAnalyzer(base).exact(base).dt;
    for (int run = 0; run < runs; ++run) {
        Model m = base;
        State s = makeState(m);
        TimestepAnalyzer ta(m);
        CutOptions co;
        co.lumping = lumping;
        CutEngine eng(co);
        Stepper stepper;
        StepOptions opt;
        opt.dt = 0.9 * dt0;
        const int nCuts = 1 + static_cast<int>(uni(rng) * 4);
        bool failed = false, inverted = false;
        for (int c = 0; c <= nCuts && !failed; ++c) {
            for (int k = 0; k < stepsBetween; ++k) {
                stepper.step(m, s, opt);
                ++st.steps;
                // Blow-up: a non-finite value, or a speed no fall or elastic recoil of these
                // objects reaches (free fall over the object's size gives ~1.5 m/s).
                const double vmax = s.v.colwise().norm().maxCoeff();
                st.maxSpeed = std::max(st.maxSpeed, vmax);
                if (s.flags.inverted > 0 && !inverted) {
                    inverted = true;
                    ++st.invertedRuns;
                }
                if (s.flags.nonFinite > 0 || !(vmax < kBlowUpSpeed)) {
                    failed = true;
                    if (st.firstFailure.empty())
                        st.firstFailure = "run " + std::to_string(run) + " cut " + std::to_string(c) + ", step " +
                                          std::to_string(k) + " after it: " + std::to_string(s.flags.nonFinite) +
                                          " non-finite nodes, max speed " + std::to_string(vmax) + " m/s";
                    break;
                }
            }
            if (c == nCuts || failed) break;
            CutSurface cs;
            for (int k = 0; k < 3; ++k) cs.point[k] = lo[k] + (0.15 + 0.7 * uni(rng)) * (hi[k] - lo[k]);
            cs.normal = Eigen::Vector3d(uni(rng) - 0.5, uni(rng) - 0.5, uni(rng) - 0.5).normalized();
            const CutResult r = eng.cut(m, s, cs);
            ++st.cuts;
            st.maxVolumeError = std::max(st.maxVolumeError, std::abs(r.volumeAfter - r.volumeBefore) / r.volumeBefore);
            st.maxMassError = std::max(st.maxMassError, std::abs(r.massAfter - r.massBefore) / r.massBefore);
            ta.update(m, r.changedElements, r.changedNodes);
            const double dt = ta.exact(m).dt;
            st.minDtRatio = std::min(st.minDtRatio, dt / dt0);
            opt.dt = dtFactor * dt;
            stepper.reset();
        }
        st.failures += failed;
        ++st.runs;
    }
    return st;
}

} // namespace cutsim
