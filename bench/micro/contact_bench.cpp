// Tool contact on the SOFA liver (596 tets, scaled to meters) with one spherical probe (radius
// 1 cm) pressed 3 mm into its top, as in assets/scenes/probe.json:
//   build/bench/cutsim_bench --benchmark_filter=Contact
// - BM_ContactQuery: the collision cost of one step (point refit, broad phase, GJK/EPA, forces).
// - BM_ContactStep: a whole explicit step with contact; steps_per_s is the achievable step rate.
// - BM_ContactStiffnessLimit: the stable penalty stiffness of the liver's mass-scaled points
//   (contact/contact.hpp stableStiffness), paid once per run.
// - BM_ContactElementBroadphase: refit of the element tree and one query with a blade's swept box.
// - BM_ContactRep*: the representations not chosen, for the cost comparison in contact/contact.hpp:
//   every surface point a collision object in a btCollisionWorld, and a refitted
//   btBvhTriangleMeshShape against the probe.
#include "mesh/broadphase.hpp"
#include "contact/contact.hpp"
#include "fem/forces.hpp"
#include "fem/integrate.hpp"
#include "mesh/io.hpp"

#include <benchmark/benchmark.h>
#include <BulletCollision/BroadphaseCollision/btDbvtBroadphase.h>
#include <btBulletCollisionCommon.h>

#include <memory>

namespace {

using namespace cutsim;

struct Liver {
    Model model;
    EmbeddedSurface surf;
    ContactPoints pts;
    ToolDef probe;
    double dt = 0;
};

// The probe scene's liver: fixed at its back and bottom, gravity off; the probe held in place or
// pressing down 1 cm/s from its 3 mm depth.
const Liver& liver() {
    static std::unique_ptr<Liver> l;
    if (l) return *l;
    l = std::make_unique<Liver>();
    ReadOptions ro;
    ro.scale = 0.0254;
    l->model = buildModel(readTetMesh(CUTSIM_DATA_DIR "/tet/sofa_liver.msh", ro), Material{});
    std::vector<int> fixedNodes;
    for (int i = 0; i < l->model.nodes(); ++i)
        if (l->model.X(2, i) < -0.043 + 0.015 || l->model.X(1, i) < 0.0055 + 0.012) fixedNodes.push_back(i);
    fixNodes(l->model, fixedNodes);
    l->model.massDamping = 20;
    l->surf = boundarySurface(l->model.tets, l->model.X);
    l->pts = contactPoints(l->surf, l->model.tets, l->model.X, 0.005);  // half the probe radius, as the run picks
    l->dt = 0.8 * 4.51e-4;                                              // 0.8 of the exact limit, as in probe.json
    l->probe.kind = ToolDef::Kind::Sphere;
    l->probe.radius = 0.01;
    scaleByMass(l->pts, l->model.invMass, referenceMass(l->pts, l->model.invMass));
    l->probe.stiffness = kDefaultStiffnessFraction * stableStiffness(l->pts, l->model, l->dt, 4.51e-4);
    l->probe.damping = 0.05;
    ToolKey a, b;
    a.pose.position << 0.0, 0.1287 + 0.01 - 0.003, 0.0039;  // 3 mm into the top, above node (0.0115, 0.1287)
    a.pose.position.x() = 0.0115;
    b = a;
    b.time = 100;
    b.pose.position.y() -= 1.0;
    l->probe.keys = {a, b};
    return *l;
}

void BM_ContactQuery(benchmark::State& st) {
    const Liver& l = liver();
    ContactWorld w({l.probe});
    w.setSurface(l.pts);
    Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, l.model.nodes()), v = f;
    w.addForces(l.model.X, v, 0, l.dt, f);
    for (auto _ : st) {
        f.setZero();
        w.addForces(l.model.X, v, 0, l.dt, f);
        benchmark::DoNotOptimize(f.data());
    }
    st.counters["points"] = w.points().points();
    st.counters["contacts"] = w.last().contacts;
    st.counters["force_N"] = w.last().reaction[0].norm();
}

void BM_ContactStep(benchmark::State& st) {
    const Liver& l = liver();
    setThreads(static_cast<int>(st.range(0)));
    ContactWorld w({l.probe});
    w.setSurface(l.pts);
    State s = makeState(l.model);
    Stepper stepper;
    const StepOptions opt{Integrator::SymplecticEuler, l.dt};
    long contacts = 0;
    for (auto _ : st) {
        s.fExt.setZero();
        w.addForces(s.x, s.v, s.time, l.dt, s.fExt);
        stepper.step(l.model, s, opt);
        contacts += w.last().contacts;
    }
    st.counters["steps_per_s"] = benchmark::Counter(static_cast<double>(st.iterations()), benchmark::Counter::kIsRate);
    st.counters["mean_contacts"] = static_cast<double>(contacts) / static_cast<double>(st.iterations());
    st.counters["hash"] = s.x.sum();
    setThreads(0);
}

void BM_ContactStiffnessLimit(benchmark::State& st) {
    const Liver& l = liver();
    double k = 0;
    for (auto _ : st) {
        k = stableStiffness(l.pts, l.model, l.dt, 4.51e-4);
        benchmark::DoNotOptimize(k);
    }
    st.counters["k_N_per_m"] = k;
}

// Every contact point a tiny sphere object in the world; the probe an object too.
void BM_ContactRepWorldProxies(benchmark::State& st) {
    const Liver& l = liver();
    // Bullet fattens proxies by 5 cm, made for metre-sized bodies; 1 mm suits this surface
    const btScalar oldMargin = gDbvtMargin;
    gDbvtMargin = 1e-3;
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher(&config);
    btDbvtBroadphase broadphase;
    btCollisionWorld world(&dispatcher, &broadphase, &config);
    btSphereShape point(1e-4), probe(l.probe.radius);
    std::vector<std::unique_ptr<btCollisionObject>> objs;
    Eigen::Matrix3Xd xp(3, l.pts.points());
    auto positions = [&] {
        for (int p = 0; p < l.pts.points(); ++p) {
            Eigen::Vector3d x = Eigen::Vector3d::Zero();
            for (int i = 0; i < l.pts.count[p]; ++i) x += l.pts.weights(i, p) * l.model.X.col(l.pts.nodes(i, p));
            xp.col(p) = x;
        }
    };
    positions();
    for (int p = 0; p < l.pts.points(); ++p) {
        auto o = std::make_unique<btCollisionObject>();
        o->setCollisionShape(&point);
        o->getWorldTransform().setOrigin(btVector3(xp(0, p), xp(1, p), xp(2, p)));
        world.addCollisionObject(o.get(), 1, 2);  // points meet only the probe
        objs.push_back(std::move(o));
    }
    auto po = std::make_unique<btCollisionObject>();
    po->setCollisionShape(&probe);
    const Eigen::Vector3d c = l.probe.keys[0].pose.position;
    po->getWorldTransform().setOrigin(btVector3(c.x(), c.y(), c.z()));
    world.addCollisionObject(po.get(), 2, 1);
    int manifolds = 0;
    for (auto _ : st) {
        positions();
        for (int p = 0; p < l.pts.points(); ++p)
            objs[p]->getWorldTransform().setOrigin(btVector3(xp(0, p), xp(1, p), xp(2, p)));
        world.performDiscreteCollisionDetection();
        manifolds = dispatcher.getNumManifolds();
    }
    st.counters["points"] = l.pts.points();
    st.counters["manifolds"] = manifolds;
    for (auto& o : objs) world.removeCollisionObject(o.get());
    world.removeCollisionObject(po.get());
    gDbvtMargin = oldMargin;
}

// The surface triangles in a btBvhTriangleMeshShape, refitted every step, against the probe.
void BM_ContactRepTriangleBvh(benchmark::State& st) {
    const Liver& l = liver();
    Eigen::Matrix3Xd xv;
    embeddedPositions(l.surf, l.model.tets, l.model.X, xv);
    std::vector<btScalar> verts(static_cast<size_t>(3 * xv.cols()));
    std::vector<int> tris(l.surf.triangles.data(), l.surf.triangles.data() + l.surf.triangles.size());
    for (Eigen::Index i = 0; i < xv.size(); ++i) verts[static_cast<size_t>(i)] = xv.data()[i];
    btTriangleIndexVertexArray array(l.surf.faces(), tris.data(), 3 * sizeof(int), static_cast<int>(xv.cols()),
                                     verts.data(), 3 * sizeof(btScalar));
    btBvhTriangleMeshShape mesh(&array, true);
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher(&config);
    btDbvtBroadphase broadphase;
    btCollisionWorld world(&dispatcher, &broadphase, &config);
    btSphereShape probe(l.probe.radius);
    btCollisionObject mo, po;
    mo.setCollisionShape(&mesh);
    po.setCollisionShape(&probe);
    const Eigen::Vector3d c = l.probe.keys[0].pose.position;
    po.getWorldTransform().setOrigin(btVector3(c.x(), c.y(), c.z()));
    world.addCollisionObject(&mo);
    world.addCollisionObject(&po);
    int points = 0;
    for (auto _ : st) {
        embeddedPositions(l.surf, l.model.tets, l.model.X, xv);
        for (Eigen::Index i = 0; i < xv.size(); ++i) verts[static_cast<size_t>(i)] = xv.data()[i];
        btVector3 lo, hi;
        mesh.getMeshInterface()->calculateAabbBruteForce(lo, hi);
        mesh.refitTree(lo, hi);
        world.updateSingleAabb(&mo);
        world.performDiscreteCollisionDetection();
        points = dispatcher.getNumManifolds() ? dispatcher.getManifoldByIndexInternal(0)->getNumContacts() : 0;
    }
    st.counters["triangles"] = l.surf.faces();
    st.counters["contact_points"] = points;
    world.removeCollisionObject(&mo);
    world.removeCollisionObject(&po);
}

void BM_ContactElementBroadphase(benchmark::State& st) {
    const Liver& l = liver();
    ToolDef blade;
    blade.kind = ToolDef::Kind::Blade;
    blade.size << 0.08, 0.03, 0.001;
    ToolKey a, b;
    a.pose.position << -0.035, 0.12, 0.013;
    b = a;
    b.time = 1;
    b.pose.position.y() = 0.0;
    blade.keys = {a, b};
    ElementBroadphase bp(0.001);
    Eigen::Matrix3Xd x = l.model.X;
    bp.refit(l.model.tets, x);
    std::vector<int> hits;
    double t = 0;
    for (auto _ : st) {
        x.row(1).array() += 1e-6;  // a small motion, as between two steps
        bp.refit(l.model.tets, x);
        Eigen::Vector3d lo, hi;
        sweptAabb(blade, t, t + 1e-3, lo, hi);  // one millisecond of the sweep
        bp.query(lo, hi, hits);
        t = t > 0.99 ? 0 : t + 1e-3;
    }
    st.counters["elements"] = l.model.elements();
    st.counters["hits_last"] = static_cast<double>(hits.size());
}

}  // namespace

BENCHMARK(BM_ContactElementBroadphase)->UseRealTime()->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ContactQuery)->UseRealTime()->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ContactStiffnessLimit)->UseRealTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ContactStep)->Arg(1)->Arg(2)->UseRealTime()->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ContactRepWorldProxies)->UseRealTime()->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ContactRepTriangleBvh)->UseRealTime()->Unit(benchmark::kMicrosecond);
