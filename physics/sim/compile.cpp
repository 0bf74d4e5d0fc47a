// A run compiled from its scene at load (Simulation's constructor): the object read, placed and
// built, its time step analysed and chosen, contact and cutting set up. What never changes after
// goes into SimSetup, the rest into SimData. Everything that can fail on bad input fails here,
// before any output.
#include "embed/mi.hpp"
#include "embed/visual.hpp"
#include "fem/forces.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "sim/stages.hpp"
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
constexpr double kBytesPerTet = 1000;      // a run's peak memory per element, with margin
constexpr double kMaxContactPoints = 5e6;  // docs/scene-format.md, contact.spacing
constexpr double kMaxVisualOutside = 0.1;  // object.visual: farthest vertex outside, of the object's size
constexpr double kOneCoreTetSteps = 3e7;   // tet-steps per second of one core (BENCHMARKS.md, step)

// Diagonal of the bounding box of X (3 x n) [m].
double boxDiagonal(const Eigen::Matrix3Xd& X) {
    if (X.cols() == 0) return 0;
    return (X.rowwise().maxCoeff() - X.rowwise().minCoeff()).norm();
}

// How the scene places its object: rotated, then translated.
struct Placement {
    Eigen::Matrix3d R;
    Eigen::Vector3d translate;
    SurfaceMesh operator()(SurfaceMesh s) const {
        s.V = (R * s.V).colwise() + translate;
        return s;
    }
};

Placement placementOf(const SceneDef& sc) {
    const double d2r = M_PI / 180.0;
    return {(Eigen::AngleAxisd(sc.rotateDeg.z() * d2r, Eigen::Vector3d::UnitZ()) *
             Eigen::AngleAxisd(sc.rotateDeg.y() * d2r, Eigen::Vector3d::UnitY()) *
             Eigen::AngleAxisd(sc.rotateDeg.x() * d2r, Eigen::Vector3d::UnitX()))
                .toRotationMatrix(),
            sc.translate};
}

// An object under a millimetre or over ten metres is most likely in the wrong units.
void checkSize(const SceneDef& sc, const Eigen::Matrix3Xd& X) {
    const double size = boxDiagonal(X);
    if (!sc.anySize && !(size >= kMinObjectSize && size <= kMaxObjectSize))
        throw InputError(sc.file + ": object.scale: " +
                         fmt("the object is %.3g m across after scale %g; cutsim works in meters: give the "
                             "scale that converts the file's units (0.001 for mm), or set object.any_size true",
                             size, sc.scale));
}

// object.visual, read and placed: the surface rides the rest mesh's elements. A vertex far outside
// every element means the surface does not belong to this mesh or has the wrong scale: refused.
void embedVisualSurface(SimSetup& s, const Model& model, const Placement& placed) {
    const SceneDef& sc = s.scene;
    // object.visual.scale when given, else object.scale
    const std::string key = sc.file + (sc.visualScale != sc.scale ? ": object.visual.scale" : ": object.scale");
    const SurfaceMesh vis = placed(readSurfaceMesh(sc.visual, sc.visualScale, key));
    Stopwatch sw;
    VisualEmbedding ve = embedVisual(vis, model.tets, model.X);
    const double size = boxDiagonal(model.X);
    if (ve.maxOutside > kMaxVisualOutside * size)
        throw InputError(sc.file + ": object.visual: " +
                         fmt("vertex %d of %s lies %.3g m outside the tet mesh, %.0f%% of its size %.3g m "
                             "(at most %.0f%%): a wrong scale or another object's surface?",
                             ve.farthest, sc.visual.c_str(), ve.maxOutside, 100 * ve.maxOutside / size, size,
                             100 * kMaxVisualOutside));
    s.visualReport = {
        {"file", sc.visual},      {"vertices", ve.surface.vertices()}, {"triangles", ve.surface.faces()},
        {"outside", ve.outside},  {"max_outside", ve.maxOutside},      {"max_outside_fraction", ve.maxOutside / size},
        {"seconds", sw.seconds()}};
    s.visual = std::make_unique<const EmbeddedSurface>(std::move(ve.surface));
}

// Mesh intersection: the placed surface in a regular lattice (thesis ch. 6).
void buildMiObject(SimSetup& s, SimData& d, const Placement& placed) {
    const SceneDef& sc = s.scene;
    Stopwatch te;
    SurfaceMesh surf = placed(readSurfaceMesh(sc.surface, sc.scale, sc.file + ": object.scale"));
    checkSize(sc, surf.V);
    MiOptions mo;
    mo.cells = sc.surfaceCells;
    mo.h = sc.surfaceH;
    mo.fixOutsideNodes = sc.surfaceFixOutside;
    mo.keepLatticeStep = sc.surfaceKeepStep;
    mo.sizeKey = sc.file + (sc.surfaceH > 0 ? ": object.surface.h" : ": object.surface.cells");
    MiResult mi = buildMi(surf, sc.material, mo);
    s.embedding = {{"h", mi.h},
                   {"interface_elements", mi.count(ElementClass::Interface)},
                   {"volume_embedded", mi.embeddedVolume()},
                   {"volume_surface", enclosedVolume(surf)},
                   {"closed", mi.closed},
                   {"fix_outside", sc.surfaceFixOutside},
                   {"seconds", te.seconds()}};
    if (sc.surfaceKeepStep) {
        const KeepStepResult& ks = mi.massScaling;
        s.embedding["keep_step"] = {{"dt_lattice", mi.dtLattice},       {"dt_before", ks.dtBefore},
                                    {"dt_after", ks.dtAfter},           {"added_mass", ks.addedMass},
                                    {"mass_fraction", ks.massFraction}, {"rounds", ks.rounds},
                                    {"seconds", mi.seconds.keepStep}};
        // More than a percent changes the dynamics visibly: say so (thin parts on a coarse lattice).
        if (ks.massFraction > kKeepStepWarnFraction || !ks.reached) {
            char text[320];
            std::snprintf(text, sizeof text,
                          "%s: object.surface.keep_step %s the lattice's step %.4g s by adding %.2f%% of the mass "
                          "(step without it %.4g s); a finer lattice needs less, keep_step false adds none",
                          sc.file.c_str(), ks.reached ? "kept" : "did not reach", mi.dtLattice, 100 * ks.massFraction,
                          ks.dtBefore);
            d.record.warnings.raise(Warning::KeepStepMass, text);
        }
    }
    d.model = std::move(mi.model);
    d.model.elementModel = sc.element;
    s.embedded = std::make_unique<const EmbeddedSurface>(std::move(mi.surface));
    s.latticeStep = mi.cellSize.minCoeff();
    // Lattice nodes of nearly empty cells are light: their motion relative to their neighbours
    // is damped as a cut's light control points are (cutting.light_share; fem/integrate.hpp),
    // else a contact correcting the heavy nodes next to them each step drives their modes,
    // which sit at the step's limit (docs/method.md, Contact).
    if (sc.cutting.lightShare > 0) markLightNodes(d.model, wholeMass(d.model), sc.cutting.lightShare);
    if (!sc.visual.empty()) embedVisualSurface(s, d.model, placed);
}

// object.tetra: the surface's mesh from the cache, or built by `cutsim tetra`'s pipeline and cached.
TetMesh tetraMesh(SimSetup& s, SimData& d) {
    const SceneDef& sc = s.scene;
    Stopwatch sw;
    TetraOptions o;
    o.size = sc.tetraSize;
    o.improve = sc.tetraImprove;
    o.mesher = sc.tetraMesher;
    o.material = sc.material;
    o.sizeKey = sc.file + ": object.tetra.size";
    bool cached = false;
    TetraReport r;
    std::string file;
    TetMesh m;
    try {
        m = tetraCached(sc.tetraSurface, sc.scale, o, cached, r, file, sc.file + ": object.scale");
    } catch (const InputError& e) {
        // the errors of object.scale and object.tetra.size name their key already
        if (std::string_view(e.what()).starts_with(sc.file + ": ")) throw;
        throw InputError(sc.file + ": object.tetra: " + e.what());
    }
    s.tetra = {{"surface", sc.tetraSurface},
               {"size", o.size},
               {"cached", cached},
               {"cache_file", file},
               {"seconds", sw.seconds()}};
    if (!cached)
        s.tetra.update({{"mesher", r.mesher},
                        {"tets", r.tets},
                        {"dt_before", r.dtBefore},
                        {"dt_after", r.dtAfter},
                        {"step_quality", r.dtAfter / r.dtScale},
                        {"volume_error", (r.volumeMesh - r.volumeSurface) / r.volumeSurface},
                        {"boundary_distance_rel", r.boundaryDistance / r.diagonal}});
    if (!cached && !r.mesherNote.empty()) s.tetra["mesher_note"] = r.mesherNote;
    if (!r.cacheError.empty())
        d.record.warnings.raise(Warning::TetraNotCached,
                                sc.tetraSurface + ": the mesh is not cached (" + r.cacheError + ")");
    return m;
}

// object.improve: a larger step from the mesh itself (thesis sec. 5.1); the fixed regions' nodes
// stay where they are, so the regions select the same nodes afterwards.
void improveOnLoad(SimSetup& s, TetMesh& mesh) {
    const SceneDef& sc = s.scene;
    ImproveOptions o = sc.improveOptions;
    o.material = sc.material;
    if (s.options.threads > 0) o.threads = s.options.threads;
    for (const auto& reg : sc.fixed) {
        const auto nodes = selectNodes(reg, mesh.X);
        o.fixedNodes.insert(o.fixedNodes.end(), nodes.begin(), nodes.end());
    }
    const ImproveReport r = improveMesh(mesh, o);
    s.improvement = {{"dt_before", r.before.dtExact},
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

// A tet mesh object: a file, the scene's arrays, object.tetra or a box.
void buildTetObject(SimSetup& s, SimData& d, const Placement& placed) {
    const SceneDef& sc = s.scene;
    ReadOptions ro;
    ro.scale = sc.scale;
    ro.reorient = sc.reorient;
    ro.scaleKey = sc.file + ": object.scale";
    const bool box = sc.mesh.empty() && !sc.meshData && sc.tetraSurface.empty();
    if (box) checkMemory(sc.file + ": object.box.cells", 6.0 * sc.boxCells.cast<double>().prod() * kBytesPerTet);
    TetMesh mesh = sc.meshData ? TetMesh{sc.scale * sc.meshData->X, sc.meshData->tets, {}, sc.meshData->source}
                   : !sc.tetraSurface.empty() ? tetraMesh(s, d)
                   : box ? boxMesh(sc.scale * sc.boxSize.x(), sc.scale * sc.boxSize.y(), sc.scale * sc.boxSize.z(),
                                   sc.boxCells.x(), sc.boxCells.y(), sc.boxCells.z())
                         : readTetMesh(sc.mesh, ro);
    mesh.X = (placed.R * mesh.X).colwise() + placed.translate;
    checkSize(sc, mesh.X);
    if (!box) checkMemory(mesh.source, mesh.elements() * kBytesPerTet);
    if (sc.improve) improveOnLoad(s, mesh);
    // A mesher's order is arbitrary: threads splitting the elements would share most nodes and
    // two threads run slower than one. Spatial order keeps a thread's nodes its own.
    if (!sc.mesh.empty() && sc.reorder) mesh = spatialOrder(mesh, &s.inputNode, &s.inputElement);
    d.model = buildModel(mesh, sc.material, sc.element);
    if (!sc.visual.empty()) embedVisualSurface(s, d.model, placed);
}

// The object's fixed nodes and masses, and the nodes each load pulls.
void selectRegions(SimSetup& s, SimData& d) {
    const SceneDef& sc = s.scene;
    Model& model = d.model;
    // Regions listing nodes name them as the mesh file numbers them.
    std::vector<int> nodeOf(s.inputNode.size());
    for (size_t n = 0; n < s.inputNode.size(); ++n) nodeOf[static_cast<size_t>(s.inputNode[n])] = static_cast<int>(n);
    auto regionNodes = [&](const Region& reg) {
        std::vector<int> nodes = selectNodes(reg, model.X);
        if (reg.kind == Region::Kind::Nodes && !nodeOf.empty())
            for (int& n : nodes) n = nodeOf[static_cast<size_t>(n)];
        // an embedded object's nodes are its lattice's: a coarse one can be what the region misses
        if (nodes.empty() && !s.embedding.is_null())
            throw InputError(sc.file + ": " + reg.path +
                             fmt(": selects no node of the lattice, whose nodes lie %.3g m apart (%s)",
                                 s.embedding["h"].get<double>(),
                                 sc.surfaceH > 0 ? "object.surface.h" : "object.surface.cells"));
        if (nodes.empty()) throw InputError(sc.file + ": " + reg.path + ": selects no node");
        return nodes;
    };
    for (const auto& reg : sc.fixed)
        for (int n : regionNodes(reg)) model.fixed[static_cast<size_t>(n)] = 1;
    updateMasses(model);
    if (model.freeDofs() == 0)
        throw InputError(sc.file + ": " + (sc.fixed.empty() ? std::string("object") : sc.fixed.back().path) + ": " +
                         fmt("every node of the object (%d) is fixed or massless: nothing can move", model.nodes()));
    for (const auto& f : sc.forces) s.loadNodes.push_back(regionNodes(f.region));
}

// Object: read, place, build.
void buildObject(SimSetup& s, SimData& d) {
    const SceneDef& sc = s.scene;
    const Placement placed = placementOf(sc);
    if (!sc.surface.empty())
        buildMiObject(s, d, placed);
    else
        buildTetObject(s, d, placed);
    Model& model = d.model;
    model.gravity = sc.gravity;
    model.massDamping = sc.damping;
    model.precision = sc.precision;
    selectRegions(s, d);
    d.record.initial = {{"nodes", model.nodes()},
                        {"elements", model.elements()},
                        {"fixed_nodes", model.nodes() - model.freeDofs() / 3},
                        {"mass", model.mass.sum()}};
    if (!sc.cutting.compare.empty()) s.rest = restMesh(model);
}

// The after-cut response's options, from the uncut object's limits (timestep/cut_response.hpp).
CutResponseOptions responseOptions(const SimSetup& s, const SimData& d, double hybridDtSim) {
    const SceneDef& sc = s.scene;
    CutResponseOptions ro;
    const bool explicitScheme = d.integrator != Integrator::BackwardEuler;
    if (!sc.hybrid && explicitScheme) ro.dtFloor = sc.cutting.stepFloor * s.initial.exact;
    ro.floorHybrid = sc.cutting.floorHybrid;
    ro.hybrid = sc.hybrid;
    ro.hybridDtSim = hybridDtSim;
    ro.hybridThreshold = sc.hybridThreshold;
    ro.exact = sc.cutting.exactAfterCut;
    // the certified step is held where it was before the cut, or at the floor when that is lower
    if (explicitScheme)
        ro.dtCertified = ro.dtFloor > 0 ? std::min(ro.dtFloor, s.initial.certified) : s.initial.certified;
    return ro;
}

// Time step: exact, certified and estimated limits, then the scene's policy (docs/method.md sec. 2-3).
void analyseStep(SimSetup& s, SimData& d) {
    const SceneDef& sc = s.scene;
    ExactResult exact;
    double hybridDtSim = 0;
    {
        const StageTimer t(d.record.stages, Stage::Timestep);  // the set-up's timestep stage
        try {
            d.analyzer = TimestepAnalyzer(d.model);
            exact = d.analyzer.exact(d.model);
        } catch (const EigenSolveError& e) {
            throw EigenSolveError(sc.file + ": " + e.what());
        }
        if (sc.hybrid) {
            // Thesis sec. 5.2.1: dt_sim = 0.95 of the exact step of the FEM object; the elements under
            // threshold x dt_sim are matched, now and after each cut.
            hybridDtSim = 0.95 * exact.dt;
            d.model.matchStiffness = sc.matchStiffness;
            const HybridResult h =
                matchCriticalCertified(d.model, d.analyzer, hybridDtSim, HybridOptions{sc.hybridThreshold}, true);
            s.hybrid = {{"dt_sim", hybridDtSim},
                        {"threshold", sc.hybridThreshold},
                        {"match_stiffness", sc.matchStiffness},
                        {"dt_fem_only", exact.dt},
                        {"matched", h.matched},
                        {"matched_share", double(h.matched) / d.model.elements()},
                        {"seconds", h.seconds}};
            exact.dt = h.dtExact;
        }
        d.limits = {exact.dt, d.analyzer.certifiedDt(), d.analyzer.minDt().r1r};
        s.initial = d.limits;
        d.response = CutResponse(responseOptions(s, d, hybridDtSim));
    }
    if (!(exact.dt > 0) || !std::isfinite(exact.dt))
        throw InputError(sc.file + ": the exact stable step of the object is " + fmt("%g", exact.dt) +
                         " s: check material (E, nu, rho), object.scale and fixed");
    applyStepPolicy(s, d, true);
    checkStepBudget(sc, d.choice.dt, d.model.elements());
    // a run that would take no step, or only one that ends past the duration, is refused: "ok"
    // always means the scene's time was simulated
    if (sc.duration < d.choice.dt * (1 - 1e-9))
        throw InputError(sc.file + ": duration: " +
                         fmt("%g s is shorter than one step of %.4g s: the run would simulate nothing of it; give a "
                             "longer duration or a smaller step",
                             sc.duration, d.choice.dt));
}

// Half the smallest tool or collider feature, so it cannot slip between contact points; a plane
// alone needs the vertices only (0).
double contactSpacing(const SceneDef& sc) {
    if (sc.contactSpacing > 0) return sc.contactSpacing;
    double spacing = 1e300;
    for (const auto& t : sc.tools)
        for (const auto& p : toolParts(t, 0))
            spacing = std::min(spacing, 0.5 * (p.hull || p.shape == ToolShape::Kind::Box
                                                   ? std::max({p.size.x(), p.size.y(), p.size.z()})
                                                   : p.size.x()));
    for (const auto& k : sc.colliders)
        if (k.kind == ColliderDef::Kind::Sphere || k.kind == ColliderDef::Kind::Box)
            spacing = std::min(spacing, k.size.maxCoeff());
    return spacing == 1e300 ? 0 : spacing;
}

// The penalty model's stiffness stays below the limit that keeps this step stable
// (contact/contact.hpp stableStiffness).
void setupPenalty(SimSetup& s, SimData& d) {
    const SceneDef& sc = s.scene;
    ContactSettings& c = s.contact;
    const double dt = d.choice.dt;
    // with on_limit = damp the step is above the limit already; give the penalty the headroom of 0.9
    c.stiffnessLimit =
        d.integrator != Integrator::BackwardEuler
            ? stableStiffness(d.contact->points(), d.model, std::min(dt, 0.9 * d.limits.exact), d.limits.exact)
            : std::numeric_limits<double>::infinity();
    for (auto& t : d.contact->tools()) {
        if (t.stiffness <= 0) {
            if (!std::isfinite(c.stiffnessLimit))
                throw InputError(sc.file + ": tools: " + t.name + ": stiffness is required with an implicit scheme");
            t.stiffness = kDefaultStiffnessFraction * c.stiffnessLimit;
        } else if (t.stiffness > c.stiffnessLimit) {
            char text[256];
            std::snprintf(
                text, sizeof text,
                "tool %s: stiffness %.4g N/m is above the stable limit %.4g N/m for dt %.3g s; using the limit",
                t.name.c_str(), t.stiffness, c.stiffnessLimit, dt);
            d.record.warnings.raise(Warning::ToolStiffnessClamped, text);
            t.stiffness = c.stiffnessLimit;
            c.clamped.push_back(t.name);
        }
        // damping ratio 0.3 on every point of mass <= massRef (k and c scale alike below it);
        // c dt / m stays below the explicit limit 2
        if (t.damping < 0) t.damping = 0.6 * std::sqrt(t.stiffness * c.massRef);
    }
    if (!sc.colliders.empty()) {
        if (!std::isfinite(c.stiffnessLimit))
            throw InputError(sc.file + ": colliders: contact.model \"penalty\" needs an explicit scheme here");
        const double k = kDefaultStiffnessFraction * c.stiffnessLimit;
        d.contact->setColliderPenalty(k, 0.6 * std::sqrt(k * c.massRef));
    }
}

// Contact: a Bullet world only when the scene has tools, colliders or contact between pieces.
// The projection model has no stiffness.
void setupContact(SimSetup& s, SimData& d) {
    const SceneDef& sc = s.scene;
    if (sc.tools.empty() && sc.colliders.empty() && !sc.pieceContact) return;
    const bool penalty = sc.contactModel == ContactModel::Penalty;
    d.contact = std::make_unique<ContactWorld>(sc.tools, sc.colliders);
    d.contact->setPieceContact(sc.pieceContact && !penalty, sc.pieceFriction);
    ContactSettings& c = s.contact;
    double spacing = contactSpacing(sc);
    // an MI surface crosses cells much smaller than its triangles: points at most half a cell
    // apart, so that every cell it crosses is held by points of its own (a surface's vertices
    // alone held a 32-cell liver by a few nodes on a floor, which crushed the cells between them)
    if (s.embedded && !(sc.contactSpacing > 0))
        spacing = spacing > 0 ? std::min(spacing, 0.5 * s.latticeStep) : 0.5 * s.latticeStep;
    c.spacing = spacing;
    // an embedded (MI) object is touched on its own fine surface, through the embedding weights;
    // each point's penalty scaled by its effective mass (contact/contact.hpp scaleByMass)
    const Model& model = d.model;
    const EmbeddedSurface touched = s.embedded ? *s.embedded : boundarySurface(model.tets, model.X);
    const double n = contactPointCount(touched, model.tets, model.X, spacing);
    if (n > kMaxContactPoints)
        throw InputError(sc.file + ": " + (sc.contactSpacing > 0 ? "contact.spacing" : "tools (the smallest size)") +
                         fmt(": contact points %.3g m apart would make %.3g of them on this surface, above the "
                             "limit of %.0e; give a larger contact.spacing",
                             spacing, n, kMaxContactPoints));
    ContactPoints pts = contactPoints(touched, model.tets, model.X, spacing);
    c.massRef = referenceMass(pts, model.invMass);
    scaleByMass(pts, model.invMass, c.massRef);
    d.contact->setSurface(std::move(pts), &model.X,
                          d.cutter ? d.cutter->virtualNodes(model) : std::vector<std::uint8_t>{});
    if (penalty)
        setupPenalty(s, d);
    else
        c.stiffnessLimit = std::numeric_limits<double>::quiet_NaN();  // none: no stiffness
}

// Cutting: the engine's bookkeeping exists only in scenes that cut (a scene pays for what it uses).
void setupCutting(SimSetup& s, SimData& d) {
    const SceneDef& sc = s.scene;
    for (size_t i = 0; i < sc.tools.size(); ++i)
        if (sc.tools[i].kind == ToolDef::Kind::Blade) s.bladeTools.push_back(static_cast<int>(i));
    if (sc.cutting.cuts.empty() && s.bladeTools.empty()) return;
    const StageTimer t(d.record.stages, Stage::Cuts);
    ensureCutter(s, d);
    if (s.bladeTools.empty()) return;
    // boxes fattened by the thinnest blade: a node moving less than that per step needs no tree update
    double margin = 1e300;
    for (int i : s.bladeTools) margin = std::min(margin, sc.tools[static_cast<size_t>(i)].size.z());
    d.bladePhase = std::make_unique<ElementBroadphase>(margin);
    s.bladeMargin = margin;
    d.lastEdge.resize(s.bladeTools.size());
    setupToughness(s, d);
}

}  // namespace

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

void compileRun(const SceneDef& scene, SimulationOptions opt, SimSetup& s, SimData& d) {
    Stopwatch setup;
    s.scene = scene;
    s.options = opt;
    d.integrator = scene.integrator;
    d.policy = scene.dt;
    if (opt.threads > 0) setThreads(opt.threads);
    buildObject(s, d);
    d.state = makeState(d.model);
    s.bounds = divergenceBounds(scene, d.model);
    analyseStep(s, d);
    setupContact(s, d);
    setupCutting(s, d);
    s.energyChecked = s.bounds.energyGrowth > 0 && scene.tools.empty() && scene.forces.empty();
    d.energyRef = totalEnergy(d.model, d.state);
    sampleEnergy(s, d);
    d.record.tool.sampleDt = 1.0 / scene.forceRate;
    if (opt.threads == 0) {
        const int cores = omp_get_num_procs();
        // small meshes gain nothing from a second thread (BENCHMARKS.md, step)
        if (cores > 1 && d.model.elements() >= 4000)
            d.tuner = std::make_unique<ThreadTuner>(cores);
        else
            setThreads(1);
    }
    d.record.wallSetup = setup.seconds();
}

}  // namespace cutsim
