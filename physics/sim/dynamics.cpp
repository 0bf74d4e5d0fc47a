// The stages of a step that push and move the object (sim/stages.hpp): loads, penalty contact,
// forces and integration, projection contact.
#include "sim/stages.hpp"

namespace cutsim {

// 1. loads: the scene's applied forces into fExt (zeroed first when loads or tools add to it)
void stepLoads(const SimSetup& s, SimData& d) {
    const SceneDef& sc = s.scene;
    if (sc.forces.empty() && !d.contact) return;
    const StageTimer t(d.record.stages, Stage::Loads);
    State& st = d.state;
    st.fExt.setZero();
    for (size_t l = 0; l < sc.forces.size(); ++l) {
        const Eigen::Vector3d f =
            sc.forces[l].force * sc.forces[l].profile.at(st.time) / static_cast<double>(s.loadNodes[l].size());
        for (int n : s.loadNodes[l]) st.fExt.col(n) += f;
    }
}

// 2. contact.model penalty: forces at the state of the step's start (projection acts after step 5)
void stepPenaltyContact(const SimSetup& s, SimData& d) {
    if (!d.contact || s.scene.contactModel == ContactModel::Projection) return;
    const StageTimer t(d.record.stages, Stage::Contact);
    State& st = d.state;
    d.contact->addForces(st.x, st.v, st.time, d.choice.dt, st.fExt);
}

// 4-5. forces and integration (fem/integrate.hpp; the node update may run inside the force stage,
// and the Stepper times its force part itself)
void stepIntegrate(const SimSetup&, SimData& d) {
    StageTimes& timer = d.record.stages;
    {
        const StageTimer t(timer, Stage::Integrate);
        d.stepper.step(d.model, d.state, d.stepOptions);
    }
    timer.reassign(Stage::Integrate, Stage::Forces, d.stepper.lastForceSeconds());
}

// 5b. contact.model projection: the points inside a tool or collider back onto its surface
void stepProjection(const SimSetup& s, SimData& d) {
    if (!d.contact || s.scene.contactModel != ContactModel::Projection) return;
    const StageTimer t(d.record.stages, Stage::Contact);
    // the nodes it moved only where a repair can use them (under stretch limiting)
    const bool repair = d.stepOptions.minStretch > 0;
    State& st = d.state;
    d.contact->project(d.model.invMass, st.time, d.choice.dt, st.x, st.v, repair ? &d.projected : nullptr);
    if (repair) d.stepper.repairInverted(d.model, st, d.stepOptions, d.projected);
}

}  // namespace cutsim
