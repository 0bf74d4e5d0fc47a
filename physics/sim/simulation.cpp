#include "sim/simulation.hpp"

#include "embed/mi.hpp"
#include "embed/visual.hpp"
#include "fem/forces.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "sim/tetra.hpp"
#include "timestep/floor.hpp"
#include "timestep/hybrid.hpp"
#include "util/memory.hpp"
#include "util/stopwatch.hpp"

#include <Eigen/Geometry>

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string_view>

namespace cutsim {

using nlohmann::json;

namespace {

constexpr double kKeepStepWarnFraction = 0.01;  // keep_step adding more of the mass than this is reported
constexpr double kMinObjectSize = 1e-3;         // [m] below or above these the scale is most likely wrong
constexpr double kMaxObjectSize = 10;
constexpr long kBoundsEvery = 4;           // steps between the speed and displacement checks
constexpr double kBytesPerTet = 1000;      // a run's peak memory per element, with margin
constexpr double kMaxContactPoints = 5e6;  // docs/scene-format.md, contact.spacing
constexpr double kMaxVisualOutside = 0.1;  // object.visual: farthest vertex outside, of the object's size
constexpr int kVisualCapLevels = 2;        // object.visual: cut faces clipped to it on 16 sub-triangles each
constexpr double kOneCoreTetSteps = 3e7;   // tet-steps per second of one core (BENCHMARKS.md, step)

std::string fmt(const char* f, auto... args) {
    char buf[512];
    std::snprintf(buf, sizeof buf, f, args...);
    return buf;
}

// Diagonal of the bounding box of X (3 x n) [m].
double boxDiagonal(const Eigen::Matrix3Xd& X) {
    if (X.cols() == 0) return 0;
    return (X.rowwise().maxCoeff() - X.rowwise().minCoeff()).norm();
}

}  // namespace

// ---- status, bounds, budget ----

const char* runStatusName(RunStatus s) {
    switch (s) {
    case RunStatus::Running: return "running";
    case RunStatus::Finished: return "ok";
    case RunStatus::Diverged: return "diverged";
    case RunStatus::Refused: return "refused";
    }
    return "?";
}

DivergenceBounds divergenceBounds(const SceneDef& sc, const Model& model) {
    DivergenceBounds b;
    b.waveSpeed = sc.material.pWaveSpeed();
    b.size = boxDiagonal(model.X);
    const double T = sc.duration, g = sc.gravity.norm();
    // The largest acceleration the scene's forces give the whole object, and how far and fast
    // the tools move (a tool can drag tissue along).
    const double mass = std::max(model.mass.sum(), 1e-300);
    double force = 0;
    for (const auto& f : sc.forces) force += f.force.norm();
    const double a = g + force / mass;
    double toolSpeed = 0, toolTravel = 0;
    for (const auto& t : sc.tools)
        for (size_t k = 1; k < t.keys.size(); ++k) {
            const double d = (t.keys[k].pose.position - t.keys[k - 1].pose.position).norm();
            const double span = t.keys[k].time - t.keys[k - 1].time;
            // a turn moves the tool's far end by its size per radian
            const double turn = t.keys[k].pose.orientation.angularDistance(t.keys[k - 1].pose.orientation) *
                                std::max({t.radius + t.length, t.size.maxCoeff(), b.size});
            toolTravel += d + turn;
            toolSpeed = std::max(toolSpeed, span > 0 ? (d + turn) / span : 0.0);
        }
    if (!sc.tools.empty()) toolSpeed = std::max(toolSpeed, toolTravel / std::max(T, 1e-300));  // a dragged tool
    b.maxSpeed = sc.checks.maxSpeed > 0 ? sc.checks.maxSpeed : sc.checks.speedFactor * b.waveSpeed + a * T + toolSpeed;
    b.maxDisplacement = sc.checks.maxDisplacement > 0
                            ? sc.checks.maxDisplacement
                            : sc.checks.displacementFactor * b.size + 0.5 * a * T * T + toolTravel;
    b.energyGrowth = sc.checks.energy ? mass * (g * b.size + 1e-4 * b.waveSpeed * b.waveSpeed) : 0;
    if (sc.minStretch == 0 && sc.checks.invertedSteps > 0) {
        b.invertedElements = std::max(10, static_cast<int>(sc.checks.invertedFraction * model.elements()));
        b.invertedSteps = sc.checks.invertedSteps;
    }
    return b;
}

void checkStepBudget(const SceneDef& sc, double dt, int elements) {
    if (!(dt > 0) || !std::isfinite(dt))
        throw InputError(sc.file + ": integrator.dt: the step " + fmt("%g", dt) + " s cannot advance the run");
    const double steps = sc.duration / dt;
    if (steps > sc.maxSteps)
        throw InputError(sc.file + ": integrator.max_steps: " +
                         fmt("duration %g s at a step of %.4g s takes %.3g steps, above integrator.max_steps %.3g "
                             "(about %.2g s of one core at %.0e tet-steps/s)",
                             sc.duration, dt, steps, sc.maxSteps, steps * elements / kOneCoreTetSteps,
                             kOneCoreTetSteps) +
                         "; raise integrator.max_steps to run it");
}

// ---- construction ----

Simulation::Simulation(const SceneDef& scene, Options opt)
    : sc_(scene), opt_(opt), integrator_(scene.integrator), policy_(scene.dt) {
    Stopwatch setup;
    if (opt_.threads > 0) setThreads(opt_.threads);
    buildObject();
    state_ = makeState(model_);
    bounds_ = divergenceBounds(sc_, model_);

    // Time step: exact, certified and estimated limits, then the scene's policy (docs/method.md sec. 2-3).
    ExactResult exact;
    const Stage outer = rec_.stages.open(Stage::Timestep);  // the set-up's timestep stage (StageTimer's open)
    try {
        ta_ = TimestepAnalyzer(model_);
        exact = ta_.exact(model_);
    } catch (const EigenSolveError& e) {
        throw EigenSolveError(sc_.file + ": " + e.what());
    }
    if (sc_.hybrid) {
        // Thesis sec. 5.2.1: dt_sim = 0.95 of the exact step of the FEM object; the elements under
        // threshold x dt_sim are matched, now and after each cut.
        hybridDtSim_ = 0.95 * exact.dt;
        model_.matchStiffness = sc_.matchStiffness;
        const HybridResult h =
            matchCriticalCertified(model_, ta_, hybridDtSim_, HybridOptions{sc_.hybridThreshold}, true);
        hybrid_ = {{"dt_sim", hybridDtSim_},
                   {"threshold", sc_.hybridThreshold},
                   {"match_stiffness", sc_.matchStiffness},
                   {"dt_fem_only", exact.dt},
                   {"matched", h.matched},
                   {"matched_share", double(h.matched) / model_.elements()},
                   {"seconds", h.seconds}};
        exact.dt = h.dtExact;
    }
    limits_ = {exact.dt, ta_.certifiedDt(), ta_.minDt().r1r};
    initial_ = limits_;
    {
        CutResponseOptions ro;
        const bool explicitScheme = integrator_ != Integrator::BackwardEuler;
        if (!sc_.hybrid && explicitScheme) ro.dtFloor = sc_.cutting.stepFloor * initial_.exact;
        ro.floorHybrid = sc_.cutting.floorHybrid;
        ro.hybrid = sc_.hybrid;
        ro.hybridDtSim = hybridDtSim_;
        ro.hybridThreshold = sc_.hybridThreshold;
        ro.exact = sc_.cutting.exactAfterCut;
        // the certified step is held where it was before the cut, or at the floor when that is lower
        if (explicitScheme)
            ro.dtCertified = ro.dtFloor > 0 ? std::min(ro.dtFloor, initial_.certified) : initial_.certified;
        response_ = CutResponse(ro);
    }
    rec_.stages.open(outer);
    if (!(exact.dt > 0) || !std::isfinite(exact.dt))
        throw InputError(sc_.file + ": the exact stable step of the object is " + fmt("%g", exact.dt) +
                         " s: check material (E, nu, rho), object.scale and fixed");
    chooseAndApply(true);
    checkStepBudget(sc_, choice_.dt, model_.elements());
    // a run that would take no step, or only one that ends past the duration, is refused: "ok"
    // always means the scene's time was simulated
    if (sc_.duration < choice_.dt * (1 - 1e-9))
        throw InputError(sc_.file + ": duration: " +
                         fmt("%g s is shorter than one step of %.4g s: the run would simulate nothing of it; give a "
                             "longer duration or a smaller step",
                             sc_.duration, choice_.dt));

    setupContact();
    // Cutting: the engine's bookkeeping exists only in scenes that cut (a scene pays for what it uses).
    for (size_t i = 0; i < sc_.tools.size(); ++i)
        if (sc_.tools[i].kind == ToolDef::Kind::Blade) bladeTools_.push_back(static_cast<int>(i));
    if (!sc_.cutting.cuts.empty() || !bladeTools_.empty()) {
        const StageTimer t(rec_.stages, Stage::Cuts);
        ensureCutter();
        if (!bladeTools_.empty()) {
            // boxes fattened by the thinnest blade: a node moving less than that per step needs no tree update
            double margin = 1e300;
            for (int i : bladeTools_) margin = std::min(margin, sc_.tools[static_cast<size_t>(i)].size.z());
            bladePhase_ = std::make_unique<ElementBroadphase>(margin);
            bladeMargin_ = margin;
            lastEdge_.resize(bladeTools_.size());
            setupToughness();
        }
    }
    energyChecked_ = bounds_.energyGrowth > 0 && sc_.tools.empty() && sc_.forces.empty();
    energyRef_ = totalEnergy(model_, state_);
    sampleEnergy();
    rec_.tool.sampleDt = 1.0 / sc_.forceRate;
    if (opt_.threads == 0) {
        const int cores = omp_get_num_procs();
        // small meshes gain nothing from a second thread (BENCHMARKS.md, step)
        if (cores > 1 && model_.elements() >= 4000)
            tuner_ = std::make_unique<ThreadTuner>(cores);
        else
            setThreads(1);
    }
    rec_.wallSetup = setup.seconds();
}

Simulation::~Simulation() = default;
Simulation::Simulation(Simulation&&) noexcept = default;
Simulation& Simulation::operator=(Simulation&&) noexcept = default;

int Simulation::threads() const { return tuner_ ? tuner_->current : cutsim::threads(); }

void Simulation::buildObject() {
    // Object: read, place, build. Everything that can fail on bad input fails before any output.
    const SceneDef& sc = sc_;
    ReadOptions ro;
    ro.scale = sc.scale;
    ro.reorient = sc.reorient;
    ro.scaleKey = sc.file + ": object.scale";
    // object.visual.scale when given, else object.scale
    const std::string visualKey = sc.file + (sc.visualScale != sc.scale ? ": object.visual.scale" : ": object.scale");
    const double d2r = M_PI / 180.0;
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(sc.rotateDeg.z() * d2r, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(sc.rotateDeg.y() * d2r, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(sc.rotateDeg.x() * d2r, Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();
    // An object under a millimetre or over ten metres is most likely in the wrong units.
    auto checkSize = [&](const Eigen::Matrix3Xd& X) {
        const double size = boxDiagonal(X);
        if (!sc.anySize && !(size >= kMinObjectSize && size <= kMaxObjectSize))
            throw InputError(sc.file + ": object.scale: " +
                             fmt("the object is %.3g m across after scale %g; cutsim works in meters: give the "
                                 "scale that converts the file's units (0.001 for mm), or set object.any_size true",
                                 size, sc.scale));
    };
    auto placed = [&](SurfaceMesh s) {  // rotated and translated as the object
        s.V = (R * s.V).colwise() + sc.translate;
        return s;
    };
    if (!sc.surface.empty()) {
        // Mesh intersection: the placed surface in a regular lattice (thesis ch. 6).
        Stopwatch te;
        SurfaceMesh surf = placed(readSurfaceMesh(sc.surface, sc.scale, ro.scaleKey));
        checkSize(surf.V);
        MiOptions mo;
        mo.cells = sc.surfaceCells;
        mo.h = sc.surfaceH;
        mo.fixOutsideNodes = sc.surfaceFixOutside;
        mo.keepLatticeStep = sc.surfaceKeepStep;
        mo.sizeKey = sc.file + (sc.surfaceH > 0 ? ": object.surface.h" : ": object.surface.cells");
        MiResult mi = buildMi(surf, sc.material, mo);
        embedding_ = {{"h", mi.h},
                      {"interface_elements", mi.count(ElementClass::Interface)},
                      {"volume_embedded", mi.embeddedVolume()},
                      {"volume_surface", enclosedVolume(surf)},
                      {"closed", mi.closed},
                      {"fix_outside", sc.surfaceFixOutside},
                      {"seconds", te.seconds()}};
        if (sc.surfaceKeepStep) {
            const KeepStepResult& ks = mi.massScaling;
            embedding_["keep_step"] = {{"dt_lattice", mi.dtLattice},       {"dt_before", ks.dtBefore},
                                       {"dt_after", ks.dtAfter},           {"added_mass", ks.addedMass},
                                       {"mass_fraction", ks.massFraction}, {"rounds", ks.rounds},
                                       {"seconds", mi.seconds.keepStep}};
            // More than a percent changes the dynamics visibly: say so (thin parts on a coarse lattice).
            if (ks.massFraction > kKeepStepWarnFraction || !ks.reached) {
                char text[320];
                std::snprintf(text, sizeof text,
                              "%s: object.surface.keep_step %s the lattice's step %.4g s by adding %.2f%% of the mass "
                              "(step without it %.4g s); a finer lattice needs less, keep_step false adds none",
                              sc.file.c_str(), ks.reached ? "kept" : "did not reach", mi.dtLattice,
                              100 * ks.massFraction, ks.dtBefore);
                rec_.warnings.raise(Warning::KeepStepMass, text);
            }
        }
        model_ = std::move(mi.model);
        model_.elementModel = sc.element;
        embedded_ = std::make_unique<EmbeddedSurface>(std::move(mi.surface));
        // Lattice nodes of nearly empty cells are light: their motion relative to their neighbours
        // is damped as a cut's light control points are (cutting.light_share; fem/integrate.hpp),
        // else a contact correcting the heavy nodes next to them each step drives their modes,
        // which sit at the step's limit (docs/method.md, Contact).
        if (sc.cutting.lightShare > 0) markLightNodes(model_, wholeMass(model_), sc.cutting.lightShare);
        if (!sc.visual.empty()) embedVisualSurface(placed(readSurfaceMesh(sc.visual, sc.visualScale, visualKey)));
    } else {
        const bool box = sc.mesh.empty() && !sc.meshData && sc.tetraSurface.empty();
        if (box) checkMemory(sc.file + ": object.box.cells", 6.0 * sc.boxCells.cast<double>().prod() * kBytesPerTet);
        TetMesh mesh = sc.meshData ? TetMesh{sc.scale * sc.meshData->X, sc.meshData->tets, {}, sc.meshData->source}
                       : !sc.tetraSurface.empty() ? tetraMesh()
                       : box ? boxMesh(sc.scale * sc.boxSize.x(), sc.scale * sc.boxSize.y(), sc.scale * sc.boxSize.z(),
                                       sc.boxCells.x(), sc.boxCells.y(), sc.boxCells.z())
                             : readTetMesh(sc.mesh, ro);
        mesh.X = (R * mesh.X).colwise() + sc.translate;
        checkSize(mesh.X);
        if (!box) checkMemory(mesh.source, mesh.elements() * kBytesPerTet);
        if (sc.improve) improveOnLoad(mesh);
        // A mesher's order is arbitrary: threads splitting the elements would share most nodes and
        // two threads run slower than one. Spatial order keeps a thread's nodes its own.
        if (!sc.mesh.empty() && sc.reorder) mesh = spatialOrder(mesh, &inputNode_, &inputElement_);
        model_ = buildModel(mesh, sc.material, sc.element);
        if (!sc.visual.empty()) embedVisualSurface(placed(readSurfaceMesh(sc.visual, sc.visualScale, visualKey)));
    }
    model_.gravity = sc.gravity;
    model_.massDamping = sc.damping;
    model_.precision = sc.precision;
    // Regions listing nodes name them as the mesh file numbers them.
    std::vector<int> nodeOf(inputNode_.size());
    for (size_t n = 0; n < inputNode_.size(); ++n) nodeOf[static_cast<size_t>(inputNode_[n])] = static_cast<int>(n);
    auto regionNodes = [&](const Region& reg) {
        std::vector<int> nodes = selectNodes(reg, model_.X);
        if (reg.kind == Region::Kind::Nodes && !nodeOf.empty())
            for (int& n : nodes) n = nodeOf[static_cast<size_t>(n)];
        // an embedded object's nodes are its lattice's: a coarse one can be what the region misses
        if (nodes.empty() && !embedding_.is_null())
            throw InputError(sc.file + ": " + reg.path +
                             fmt(": selects no node of the lattice, whose nodes lie %.3g m apart (%s)",
                                 embedding_["h"].get<double>(),
                                 sc.surfaceH > 0 ? "object.surface.h" : "object.surface.cells"));
        if (nodes.empty()) throw InputError(sc.file + ": " + reg.path + ": selects no node");
        return nodes;
    };
    for (const auto& reg : sc.fixed)
        for (int n : regionNodes(reg)) model_.fixed[static_cast<size_t>(n)] = 1;
    updateMasses(model_);
    if (model_.freeDofs() == 0)
        throw InputError(sc.file + ": " + (sc.fixed.empty() ? std::string("object") : sc.fixed.back().path) + ": " +
                         fmt("every node of the object (%d) is fixed or massless: nothing can move", model_.nodes()));
    for (const auto& f : sc.forces) loadNodes_.push_back(regionNodes(f.region));
    rec_.initial = {{"nodes", model_.nodes()},
                    {"elements", model_.elements()},
                    {"fixed_nodes", model_.nodes() - model_.freeDofs() / 3},
                    {"mass", model_.mass.sum()}};
    if (!sc.cutting.compare.empty()) rest_ = restMesh(model_);
}

// object.tetra: the surface's mesh from the cache, or built by `cutsim tetra`'s pipeline and cached.
TetMesh Simulation::tetraMesh() {
    Stopwatch sw;
    TetraOptions o;
    o.size = sc_.tetraSize;
    o.improve = sc_.tetraImprove;
    o.material = sc_.material;
    o.sizeKey = sc_.file + ": object.tetra.size";
    bool cached = false;
    TetraReport r;
    std::string file;
    TetMesh m;
    try {
        m = tetraCached(sc_.tetraSurface, sc_.scale, o, cached, r, file, sc_.file + ": object.scale");
    } catch (const InputError& e) {
        // the errors of object.scale and object.tetra.size name their key already
        if (std::string_view(e.what()).starts_with(sc_.file + ": ")) throw;
        throw InputError(sc_.file + ": object.tetra: " + e.what());
    }
    tetra_ = {{"surface", sc_.tetraSurface},
              {"size", o.size},
              {"cached", cached},
              {"cache_file", file},
              {"seconds", sw.seconds()}};
    if (!cached)
        tetra_.update({{"dt_before", r.dtBefore},
                       {"dt_after", r.dtAfter},
                       {"step_quality", r.dtAfter / r.dtScale},
                       {"volume_error", (r.volumeMesh - r.volumeSurface) / r.volumeSurface},
                       {"boundary_distance_rel", r.boundaryDistance / r.diagonal}});
    if (!r.cacheError.empty())
        rec_.warnings.raise(Warning::TetraNotCached,
                            sc_.tetraSurface + ": the mesh is not cached (" + r.cacheError + ")");
    return m;
}

// object.visual: the surface rides the rest mesh's elements. A vertex far outside every element
// means the surface does not belong to this mesh or has the wrong scale: refused.
void Simulation::embedVisualSurface(const SurfaceMesh& vis) {
    Stopwatch sw;
    VisualEmbedding ve = embedVisual(vis, model_.tets, model_.X);
    const double size = boxDiagonal(model_.X);
    if (ve.maxOutside > kMaxVisualOutside * size)
        throw InputError(sc_.file + ": object.visual: " +
                         fmt("vertex %d of %s lies %.3g m outside the tet mesh, %.0f%% of its size %.3g m "
                             "(at most %.0f%%): a wrong scale or another object's surface?",
                             ve.farthest, sc_.visual.c_str(), ve.maxOutside, 100 * ve.maxOutside / size, size,
                             100 * kMaxVisualOutside));
    visualReport_ = {
        {"file", sc_.visual},     {"vertices", ve.surface.vertices()}, {"triangles", ve.surface.faces()},
        {"outside", ve.outside},  {"max_outside", ve.maxOutside},      {"max_outside_fraction", ve.maxOutside / size},
        {"seconds", sw.seconds()}};
    visual_ = std::make_unique<EmbeddedSurface>(std::move(ve.surface));
}

const EmbeddedSurface* Simulation::surface() const {
    if (drawnStale_ && opt_.renderSurface && !visual_) {  // blade steps since the last refresh
        surface_ = std::make_unique<EmbeddedSurface>(embedded_ ? cutter_->surface(model_, *embedded_)
                                                               : cutter_->surface(model_));
        drawnStale_ = false;
    }
    if (visualStale_) {
        surface_ = std::make_unique<EmbeddedSurface>(cutter_->surface(model_, *visual_, kVisualCapLevels));
        visualStale_ = false;
    }
    return surface_ ? surface_.get() : visual_ ? visual_.get() : embedded_.get();
}

// object.improve: a larger step from the mesh itself (thesis sec. 5.1); the fixed regions' nodes
// stay where they are, so the regions select the same nodes afterwards.
void Simulation::improveOnLoad(TetMesh& mesh) {
    const SceneDef& sc = sc_;
    ImproveOptions o = sc.improveOptions;
    o.material = sc.material;
    if (opt_.threads > 0) o.threads = opt_.threads;
    for (const auto& reg : sc.fixed) {
        const auto nodes = selectNodes(reg, mesh.X);
        o.fixedNodes.insert(o.fixedNodes.end(), nodes.begin(), nodes.end());
    }
    const ImproveReport r = improveMesh(mesh, o);
    improvement_ = {{"dt_before", r.before.dtExact},
                    {"dt_after", r.after.dtExact},
                    {"gain", r.after.dtExact / r.before.dtExact},
                    {"tets_before", r.before.tets},
                    {"tets_after", r.after.tets},
                    {"min_dihedral_before", r.before.minDihedralDeg},
                    {"min_dihedral_after", r.after.minDihedralDeg},
                    {"volume_change", r.volumeChange},
                    {"boundary_distance", r.boundaryDistance},
                    {"rounds", r.rounds},
                    {"seconds", r.seconds.back().second}};
}

// The step from the scene's policy at the current limits (sim/step_policy.hpp), with its
// per-element damping and critical elements. Before the first step a refused step is bad input;
// after a cut it stops the run (exit 4) and the step stays as it was.
void Simulation::chooseAndApply(bool initial) {
    const bool explicitScheme = integrator_ != Integrator::BackwardEuler;
    const StepChoice c = chooseStep(policy_, limits_, explicitScheme);
    if (c.action == LimitAction::Refused) {
        if (initial)
            throw InputError(sc_.file + ": integrator.dt: " +
                             fmt("step %.6g s is above the exact stable limit %.6g s of %s", c.dt, c.limit,
                                 integratorName(integrator_)) +
                             "; set integrator.dt.on_limit to \"clamp\" or \"damp\" to allow it");
        fail(RunStatus::Refused, fmt("stopped: step %.6g s is above the stable limit %.6g s after the cut at t = %.4g s"
                                     " (integrator.dt.on_limit is \"refuse\")",
                                     c.dt, c.limit, state_.time));
        choice_.action = LimitAction::Refused;
        return;
    }
    choice_ = c;
    // Per-element damping factor alpha_e = (dt_e / dt)^2 where dt_e < dt (thesis eq. 3.16).
    if (c.action == LimitAction::Damped)
        alphaElem_ = elementAlpha(ta_.estimates().r1r, c.dt);
    else
        alphaElem_.resize(0);
    critical_ = 0;
    const Eigen::VectorXd& r1r = ta_.estimates().r1r;
    for (Eigen::Index e = 0; e < r1r.size(); ++e) critical_ += r1r(e) < sc_.capture.criticalFactor * c.dt;
    so_ = sc_.stepOptions(integrator_, c.dt, alphaElem_);
}

void Simulation::setupContact() {
    // Contact: a Bullet world only when the scene has tools, colliders or contact between pieces.
    // The projection model has no stiffness; the penalty model's stays below the limit that keeps
    // this step stable (contact/contact.hpp stableStiffness).
    if (sc_.tools.empty() && sc_.colliders.empty() && !sc_.pieceContact) return;
    const double dt = choice_.dt;
    const bool explicitScheme = integrator_ != Integrator::BackwardEuler;
    const bool penalty = sc_.contactModel == ContactModel::Penalty;
    contact_ = std::make_unique<ContactWorld>(sc_.tools, sc_.colliders);
    contact_->setPieceContact(sc_.pieceContact && !penalty, sc_.pieceFriction);
    ContactSettings& c = contactSettings_;
    double spacing = sc_.contactSpacing;
    if (spacing <= 0) {
        // half the smallest tool or collider feature, so it cannot slip between points; a plane
        // alone needs the vertices only
        spacing = 1e300;
        for (const auto& t : sc_.tools)
            for (const auto& p : toolParts(t, 0))
                spacing = std::min(spacing, 0.5 * (p.hull || p.shape == ToolShape::Kind::Box
                                                       ? std::max({p.size.x(), p.size.y(), p.size.z()})
                                                       : p.size.x()));
        for (const auto& k : sc_.colliders)
            if (k.kind == ColliderDef::Kind::Sphere || k.kind == ColliderDef::Kind::Box)
                spacing = std::min(spacing, k.size.maxCoeff());
        if (spacing == 1e300) spacing = 0;
    }
    c.spacing = spacing;
    // an embedded (MI) object is touched on its own fine surface, through the embedding weights;
    // each point's penalty scaled by its effective mass (contact/contact.hpp scaleByMass)
    const EmbeddedSurface touched = embedded_ ? *embedded_ : boundarySurface(model_.tets, model_.X);
    const double n = contactPointCount(touched, model_.tets, model_.X, spacing);
    if (n > kMaxContactPoints)
        throw InputError(sc_.file + ": " + (sc_.contactSpacing > 0 ? "contact.spacing" : "tools (the smallest size)") +
                         fmt(": contact points %.3g m apart would make %.3g of them on this surface, above the "
                             "limit of %.0e; give a larger contact.spacing",
                             spacing, n, kMaxContactPoints));
    ContactPoints pts = contactPoints(touched, model_.tets, model_.X, spacing);
    c.massRef = referenceMass(pts, model_.invMass);
    scaleByMass(pts, model_.invMass, c.massRef);
    contact_->setSurface(std::move(pts), &model_.X,
                         cutter_ ? cutter_->virtualNodes(model_) : std::vector<std::uint8_t>{});
    if (!penalty) {
        c.stiffnessLimit = std::numeric_limits<double>::quiet_NaN();  // none: no stiffness
        return;
    }
    // with on_limit = damp the step is above the limit already; give the penalty the headroom of 0.9
    c.stiffnessLimit =
        explicitScheme ? stableStiffness(contact_->points(), model_, std::min(dt, 0.9 * limits_.exact), limits_.exact)
                       : std::numeric_limits<double>::infinity();
    for (auto& t : contact_->tools()) {
        if (t.stiffness <= 0) {
            if (!std::isfinite(c.stiffnessLimit))
                throw InputError(sc_.file + ": tools: " + t.name + ": stiffness is required with an implicit scheme");
            t.stiffness = kDefaultStiffnessFraction * c.stiffnessLimit;
        } else if (t.stiffness > c.stiffnessLimit) {
            char text[256];
            std::snprintf(
                text, sizeof text,
                "tool %s: stiffness %.4g N/m is above the stable limit %.4g N/m for dt %.3g s; using the limit",
                t.name.c_str(), t.stiffness, c.stiffnessLimit, dt);
            rec_.warnings.raise(Warning::ToolStiffnessClamped, text);
            t.stiffness = c.stiffnessLimit;
            c.clamped.push_back(t.name);
        }
        // damping ratio 0.3 on every point of mass <= massRef (k and c scale alike below it);
        // c dt / m stays below the explicit limit 2
        if (t.damping < 0) t.damping = 0.6 * std::sqrt(t.stiffness * c.massRef);
    }
    if (!sc_.colliders.empty()) {
        if (!std::isfinite(c.stiffnessLimit))
            throw InputError(sc_.file + ": colliders: contact.model \"penalty\" needs an explicit scheme here");
        const double k = kDefaultStiffnessFraction * c.stiffnessLimit;
        contact_->setColliderPenalty(k, 0.6 * std::sqrt(k * c.massRef));
    }
}

void Simulation::ensureCutter() {
    if (cutter_) return;
    cutter_ = std::make_unique<CutEngine>(cutOptions(sc_.cutting));
    cutter_->prepare(model_);
    // room for the cuts' elements now, not at the first cut (fem/state.hpp)
    const Eigen::Index ne = model_.elements();
    reserveElements(model_, state_, ne + ne / 4 + 16);
}

// ---- the step ----

bool Simulation::finished() const { return state_.time >= sc_.duration - 1e-9 * choice_.dt; }

RunStatus Simulation::step() {
    if (status_ != RunStatus::Running) return status_;
    if (finished()) return status_ = RunStatus::Finished;
    const Stopwatch whole;
    StageTimes& timer = rec_.stages;  // each stage a StageTimer scope (record.hpp)
    // 1. loads: the scene's applied forces into fExt (zeroed first when loads or tools add to it)
    if (!sc_.forces.empty() || contact_) {
        const StageTimer t(timer, Stage::Loads);
        state_.fExt.setZero();
        for (size_t l = 0; l < sc_.forces.size(); ++l) {
            const Eigen::Vector3d f =
                sc_.forces[l].force * sc_.forces[l].profile.at(state_.time) / static_cast<double>(loadNodes_[l].size());
            for (int n : loadNodes_[l]) state_.fExt.col(n) += f;
        }
    }
    // 2. contact: penalty forces at the state of the step's start (projection acts after step 5)
    const double tStep = state_.time;
    const bool projection = contact_ && sc_.contactModel == ContactModel::Projection;
    if (contact_ && !projection) {
        const StageTimer t(timer, Stage::Contact);
        contact_->addForces(state_.x, state_.v, state_.time, choice_.dt, state_.fExt);
    }
    // 3. cuts: scripted cuts due now, blade sweeps over [t, t + dt]; each is a topology change
    // (the after-cut step and contact points inside it are their own stages)
    if (cutter_) {
        const StageTimer t(timer, Stage::Cuts);
        if (!(applyDueCuts() && applyBlades())) return status_;
    }
    // 4-5. forces and integration (fem/integrate.hpp; the node update may run inside the force
    // stage, and the Stepper times its force part itself)
    so_.alphaElem = alphaElem_.size() ? &alphaElem_ : nullptr;  // this object's, also after a move
    {
        const StageTimer t(timer, Stage::Integrate);
        stepper_.step(model_, state_, so_);
    }
    timer.reassign(Stage::Integrate, Stage::Forces, stepper_.lastForceSeconds());
    if (tough_) {  // the blade's edge on the crack front (cut/toughness.hpp)
        const StageTimer t(timer, Stage::Contact);
        pressFront();
    }
    // 5b. projection contact: the points inside a tool or collider back onto its surface
    if (projection) {
        const StageTimer t(timer, Stage::Contact);
        // the nodes it moved only where a repair can use them (light nodes under stretch limiting)
        const bool repair = so_.minStretch > 0 && !model_.lightNodes.empty();
        contact_->project(model_.invMass, state_.time, choice_.dt, state_.x, state_.v, repair ? &projected_ : nullptr);
        if (repair) stepper_.repairInverted(model_, state_, so_, projected_);
    }
    // 6. checks
    {
        const StageTimer t(timer, Stage::Checks);
        if (contact_) {
            const ContactStep& st = contact_->last();
            Eigen::Vector3d f = Eigen::Vector3d::Zero();
            for (const auto& r : st.reaction) f += r;
            if (tough_) f += recordFront(tStep, st);
            rec_.tool.add(tStep, choice_.dt, f, st.maxDepth, st.contacts);
        }
        check();
        if (status_ == RunStatus::Running) sampleEnergy();
    }
    const double total = whole.seconds();
    rec_.wallLoop += total;
    if (tuner_) tuner_->after(total);
    if (status_ == RunStatus::Running && finished()) status_ = RunStatus::Finished;
    return status_;
}

RunStatus Simulation::advance(double until) {
    while (status_ == RunStatus::Running && state_.time < until - 1e-12 && !finished()) step();
    if (status_ == RunStatus::Running && finished()) status_ = RunStatus::Finished;
    return status_;
}

std::uint64_t Simulation::stateHash() const {
    std::uint64_t h = 1469598103934665603ull;
    auto mix = [&](const Eigen::Matrix3Xd& m) {
        const auto* p = reinterpret_cast<const unsigned char*>(m.data());
        for (size_t i = 0; i < static_cast<size_t>(m.size()) * sizeof(double); ++i) h = (h ^ p[i]) * 1099511628211ull;
    };
    mix(state_.x);
    mix(state_.v);
    return h;
}

void Simulation::finish() {
    // the open stroke ends with the run: the report's limits are known at the end
    if (status_ == RunStatus::Running || status_ == RunStatus::Finished) endStroke();
    if (status_ == RunStatus::Running && finished()) status_ = RunStatus::Finished;
    if (status_ == RunStatus::Diverged) return;
    nextSample_ = state_.time;  // the final state always
    sampleEnergy();
}

void Simulation::fail(RunStatus s, const std::string& why) {
    status_ = s;
    message_ = why;
}

// Numerical trouble of the last step (State::flags), and the divergence bounds.
void Simulation::check() {
    const StepFlags& fl = state_.flags;
    if (fl.inverted > 0) {
        ++rec_.invertedSteps;
        rec_.maxInverted = std::max(rec_.maxInverted, fl.inverted);
    }
    if (fl.limited > 0) {
        ++rec_.limitedSteps;
        rec_.maxLimited = std::max(rec_.maxLimited, fl.limited);
    }
    const int it = stepper_.lastSolverIterations();
    rec_.solverIterations += it;
    rec_.solverIterationsMax = std::max(rec_.solverIterationsMax, it);
    auto damped = [&]() -> std::string {
        return choice_.action == LimitAction::Damped ? fmt("; integrator.dt.on_limit \"damp\" could not hold a step of "
                                                           "%.4g s, %.3g x the exact limit %.4g s",
                                                           choice_.dt, choice_.dt / choice_.limit, choice_.limit)
                                                     : std::string();
    };
    if (fl.nonFinite > 0) {
        fail(RunStatus::Diverged,
             fmt("diverged: non-finite positions or velocities at step %ld (t = %.6g s)", state_.steps, state_.time) +
                 damped());
        return;
    }
    if (bounds_.invertedSteps > 0) {
        invertedRun_ = fl.inverted > bounds_.invertedElements ? invertedRun_ + 1 : 0;
        if (invertedRun_ >= bounds_.invertedSteps) {
            fail(RunStatus::Diverged,
                 fmt("diverged: more than %d elements inverted for %d steps in a row (%d at t = %.6g s); "
                     "integrator.min_stretch limits stretch, checks.inverted_steps sets the count",
                     bounds_.invertedElements, invertedRun_, fl.inverted, state_.time) +
                     damped());
            return;
        }
    }
    // Speeds and displacements against the scene's bounds, every few steps: a blow-up grows by a
    // factor per step and is caught while still finite, at a fraction of a percent of the step.
    if (state_.steps % kBoundsEvery != 0) return;
    double v2 = 0, d2 = 0;
    int vNode = -1, dNode = -1;
    const double *x = state_.x.data(), *v0 = state_.v.data(), *X = model_.X.data();
    for (int i = 0; i < model_.nodes(); ++i) {
        const double* vi = v0 + 3 * i;
        const double dx = x[3 * i] - X[3 * i], dy = x[3 * i + 1] - X[3 * i + 1], dz = x[3 * i + 2] - X[3 * i + 2];
        const double sv = vi[0] * vi[0] + vi[1] * vi[1] + vi[2] * vi[2], sd = dx * dx + dy * dy + dz * dz;
        if (sv > v2) v2 = sv, vNode = i;
        if (sd > d2) d2 = sd, dNode = i;
    }
    const double v = std::sqrt(v2), d = std::sqrt(d2);
    rec_.maxSpeed = std::max(rec_.maxSpeed, v);
    rec_.maxDisplacement = std::max(rec_.maxDisplacement, d);
    if (v > bounds_.maxSpeed) {
        fail(RunStatus::Diverged,
             fmt("diverged: node %d moves at %.3g m/s at step %ld (t = %.6g s), above the bound %.3g m/s "
                 "(checks.speed_factor %g x the p-wave speed %.3g m/s, plus gravity, loads and tools)",
                 vNode, v, state_.steps, state_.time, bounds_.maxSpeed, sc_.checks.speedFactor, bounds_.waveSpeed) +
                 damped());
        return;
    }
    if (d > bounds_.maxDisplacement) {
        fail(RunStatus::Diverged,
             fmt("diverged: node %d is %.3g m from its rest position at step %ld (t = %.6g s), above the bound "
                 "%.3g m (checks.displacement_factor %g x the object's size %.3g m, plus gravity, loads and tools)",
                 dNode, d, state_.steps, state_.time, bounds_.maxDisplacement, sc_.checks.displacementFactor,
                 bounds_.size) +
                 damped());
    }
}

// Energy at the capture rate: the report's samples, and the growth check when nothing does work.
void Simulation::sampleEnergy() {
    if (state_.time < nextSample_ - 1e-12) return;
    nextSample_ += 1.0 / sc_.capture.fps;
    if (nextSample_ <= state_.time) nextSample_ = state_.time + 1.0 / sc_.capture.fps;
    const double ek = kineticEnergy(model_, state_), ee = elasticEnergy(model_, state_),
                 eg = gravityEnergy(model_, state_);
    const double total = ek + ee + eg;
    rec_.energy.push_back({{"time", state_.time}, {"kinetic", ek}, {"elastic", ee}, {"gravity", eg}, {"total", total}});
    if (energyChecked_ && total - energyRef_ > bounds_.energyGrowth)
        fail(RunStatus::Diverged,
             fmt("diverged: the total energy rose by %.3g J by t = %.6g s with no work done by loads or tools "
                 "(bound %.3g J: the object's weight lifted through its size, or a 1%% strain)",
                 total - energyRef_, state_.time, bounds_.energyGrowth) +
                 (choice_.action == LimitAction::Damped
                      ? fmt("; integrator.dt.on_limit \"damp\" could not hold a step of %.4g s, %.3g x the exact "
                            "limit %.4g s",
                            choice_.dt, choice_.dt / choice_.limit, choice_.limit)
                      : std::string()));
}

// ---- interactive control ----

void Simulation::holdTool(int i, const Eigen::Vector3d& position,
                          const std::optional<Eigen::Quaterniond>& orientation) {
    if (!contact_ || i < 0 || i >= static_cast<int>(contact_->tools().size())) return;
    holdToolKeys(contact_->tools()[static_cast<size_t>(i)], state_.time, position, orientation);
    take_.holds.push_back({i, state_.time, position, orientation});
}

std::string Simulation::setPolicy(Integrator integrator, const StepPolicy& policy) {
    if (const char* why = precisionConflict(integrator, sc_.precision))
        return sc_.file + ": integrator.precision: " + why;
    const StepChoice c = chooseStep(policy, limits_, integrator != Integrator::BackwardEuler);
    if (c.action == LimitAction::Refused)
        return fmt("step %.6g s is above the exact stable limit %.6g s of %s (integrator.dt.on_limit is \"refuse\")",
                   c.dt, c.limit, integratorName(integrator));
    integrator_ = integrator;
    policy_ = policy;
    chooseAndApply(false);
    stepper_.reset();
    return {};
}

}  // namespace cutsim
