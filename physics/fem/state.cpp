#include "fem/state.hpp"

namespace cutsim {

State makeState(const Model& m) {
    State s;
    s.x = m.X;
    s.v = Eigen::Matrix3Xd::Zero(3, m.nodes());
    s.f = Eigen::Matrix3Xd::Zero(3, m.nodes());
    s.a = Eigen::Matrix3Xd::Zero(3, m.nodes());
    s.fExt = Eigen::Matrix3Xd::Zero(3, m.nodes());
    resizeState(m, s);
    return s;
}

void resizeState(const Model& m, State& s) {
    const Eigen::Index old = s.rot.cols();
    s.rot.conservativeResize(9, m.elements());
    for (Eigen::Index e = old; e < m.elements(); ++e) s.rot.col(e) << 1, 0, 0, 0, 1, 0, 0, 0, 1;
    s.fe.resize(12, m.elements());
    const Eigen::Index oldN = s.x.cols();
    if (oldN != m.nodes()) {
        for (auto* mat : {&s.x, &s.v, &s.f, &s.a, &s.fExt}) mat->conservativeResize(3, m.nodes());
        for (Eigen::Index i = oldN; i < m.nodes(); ++i) {
            s.x.col(i) = m.X.col(i);
            s.v.col(i).setZero();
            s.f.col(i).setZero();
            s.a.col(i).setZero();
            s.fExt.col(i).setZero();
        }
    }
}

void reserveElements(Model& m, State& s, Eigen::Index elements) {
    auto reserve = [elements](auto& a) {
        if (a.cols() < elements) a.conservativeResize(Eigen::NoChange, elements);
    };
    reserve(m.DmInv);
    reserve(s.rot);
    reserve(s.fe);
}

}  // namespace cutsim
