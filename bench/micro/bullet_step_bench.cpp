// Step throughput of cutsim beside Bullet's deformable-body solver, on the meshes of
// `cutsim bench step`: boxes of 6 n^3 tets, 1 cm cubes, clamped at x = 0, gravity -z, started
// rigidly rotated by 0.3 rad about y (--unrotated: at the rest shape), E 30 kPa, nu 0.3,
// rho 1000 kg/m^3, dt 1 us, one thread.
//
// cutsim: symplectic Euler, corotational linear tets, double- and single-precision element forces.
// Bullet (libbullet-dev, double precision): btDeformableMultiBodyDynamicsWorld, explicit scheme
// (setImplicit(false)), btDeformableLinearElasticityForce (corotated linear elasticity) and
// btDeformableGravityForce, every other setting left at its default. Its damping is run at 0 (as
// cutsim's model here) and at its default (alpha = beta = 0.01).
//
// Both step the same mesh with the same lumped masses from the same state. Before timing, a
// rotated box at rest shows each rotation's error, and both take the same steps and the largest
// distance between their nodes is printed. Then the configurations take turns in windows of
// --seconds, --rounds times; the table gives the median of each over its windows and the median
// of the per-round ratios, and the shares of Bullet's step from its own profile zones.
//   build/bench/cutsim_bullet_bench [--seconds S] [--rounds R] [--unrotated] [--tiny] [--json]
#include "bench/machine.hpp"
#include "bench/step_box.hpp"
#include "fem/forces.hpp"
#include "fem/integrate.hpp"
#include "mesh/generate.hpp"

#include <BulletSoftBody/btDeformableBodySolver.h>
#include <BulletSoftBody/btDeformableGravityForce.h>
#include <BulletSoftBody/btDeformableLinearElasticityForce.h>
#include <BulletSoftBody/btDeformableMultiBodyConstraintSolver.h>
#include <BulletSoftBody/btDeformableMultiBodyDynamicsWorld.h>
#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyHelpers.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <LinearMath/btQuickprof.h>
#include <btBulletDynamicsCommon.h>

#include <nlohmann/json.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <utility>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <vector>

using namespace cutsim;

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

constexpr double kDt = 1e-6;  // [s], as `cutsim bench step`

// The box of `cutsim bench step`, with or without its gravity.
Model boxModel(int n, bool gravity = true) {
    Model m = stepBox(n);
    if (!gravity) m.gravity.setZero();
    return m;
}

Eigen::Matrix3d startRotation() { return Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix(); }

// One Bullet world holding the model's mesh as one deformable body.
struct BulletBox {
    btSoftBodyRigidBodyCollisionConfiguration config;
    btCollisionDispatcher dispatcher{&config};
    btDbvtBroadphase broadphase;
    btDeformableBodySolver bodySolver;
    btDeformableMultiBodyConstraintSolver solver;
    std::unique_ptr<btDeformableMultiBodyDynamicsWorld> world;
    btSoftBody* body = nullptr;
    std::unique_ptr<btDeformableLinearElasticityForce> elastic;
    std::unique_ptr<btDeformableGravityForce> gravity;

    explicit BulletBox(const Model& m) {
        const bool withGravity = m.gravity.squaredNorm() > 0;
        solver.setDeformableSolver(&bodySolver);
        world = std::make_unique<btDeformableMultiBodyDynamicsWorld>(&dispatcher, &broadphase, &solver, &config,
                                                                     &bodySolver);
        const btVector3 g(m.gravity.x(), m.gravity.y(), m.gravity.z());
        world->setGravity(g);
        world->getWorldInfo().m_gravity = g;
        world->setImplicit(false);

        // The body as Bullet's own mesh loaders build it (btSoftBodyHelpers::CreateFromVtkFile):
        // nodes at the rest positions, tets, boundary faces, then the rest shape matrices.
        std::vector<btVector3> x(m.nodes());
        for (int i = 0; i < m.nodes(); ++i) x[i] = btVector3(m.X(0, i), m.X(1, i), m.X(2, i));
        body = new btSoftBody(&world->getWorldInfo(), m.nodes(), x.data(), nullptr);
        for (int e = 0; e < m.elements(); ++e)
            body->appendTetra(m.tets(0, e), m.tets(1, e), m.tets(2, e), m.tets(3, e));
        btSoftBodyHelpers::generateBoundaryFaces(body);
        body->initializeDmInverse();
        body->m_tetraScratches.resize(body->m_tetras.size());
        body->m_tetraScratchesTn.resize(body->m_tetras.size());
        // cutsim's lumped masses (rho V / 4 per corner); fixed nodes get mass 0, Bullet's anchor.
        for (int i = 0; i < m.nodes(); ++i) body->setMass(i, m.fixed[i] ? 0.0 : m.mass[i]);
        body->m_sleepingThreshold = 0;
        body->setActivationState(DISABLE_DEACTIVATION);
        world->addSoftBody(body);

        elastic = std::make_unique<btDeformableLinearElasticityForce>(m.material.mu(), m.material.lambda(), 0.0, 0.0);
        gravity = std::make_unique<btDeformableGravityForce>(g);
        world->addForce(body, elastic.get());
        if (withGravity) world->addForce(body, gravity.get());
    }
    ~BulletBox() {
        world->removeSoftBody(body);
        delete body;
    }
    BulletBox(const BulletBox&) = delete;
    BulletBox& operator=(const BulletBox&) = delete;

    void setPositions(const Eigen::Matrix3Xd& xs) {
        for (int i = 0; i < body->m_nodes.size(); ++i) {
            btSoftBody::Node& n = body->m_nodes[i];
            n.m_x = n.m_q = btVector3(xs(0, i), xs(1, i), xs(2, i));
            n.m_v = n.m_vn = btVector3(0, 0, 0);
        }
    }
    void step() { world->stepSimulation(kDt, 0); }  // maxSubSteps 0: one step of exactly kDt
    double distance(const Eigen::Matrix3Xd& xs) const {
        double d = 0;
        for (int i = 0; i < body->m_nodes.size(); ++i) {
            const btVector3& p = body->m_nodes[i].m_x;
            d = std::max(d, (Eigen::Vector3d(p.x(), p.y(), p.z()) - xs.col(i)).norm());
        }
        return d;
    }
};

// Bullet's own profile zones (BT_PROFILE), timed through its custom zone hooks: seconds per
// zone path ("internalSingleStepSimulation/predictUnconstraintMotion/...").
struct ZoneClock {
    static inline std::vector<std::pair<std::string, Clock::time_point>> open;
    static inline std::map<std::string, double> seconds;
    static void enter(const char* name) {
        open.emplace_back(open.empty() ? std::string(name) : open.back().first + "/" + name, Clock::now());
    }
    static void leave() {
        seconds[open.back().first] += since(open.back().second);
        open.pop_back();
    }
};

// Shares of Bullet's step by what it does, from its zones over `steps` steps.
nlohmann::json bulletStages(BulletBox& bb, int steps) {
    ZoneClock::seconds.clear();
    auto* enter0 = btGetCurrentEnterProfileZoneFunc();
    auto* leave0 = btGetCurrentLeaveProfileZoneFunc();
    btSetCustomEnterProfileZoneFunc(&ZoneClock::enter);
    btSetCustomLeaveProfileZoneFunc(&ZoneClock::leave);
    const auto t0 = Clock::now();
    for (int k = 0; k < steps; ++k) bb.step();
    const double total = since(t0);
    btSetCustomEnterProfileZoneFunc(enter0);
    btSetCustomLeaveProfileZoneFunc(leave0);
    const std::string top = "internalSingleStepSimulation/";
    auto zone = [&](const std::string& z) { return ZoneClock::seconds[top + z]; };
    const double predict = zone("predictUnconstraintMotion");
    const double collisionPrep = zone("predictUnconstraintMotion/btDeformableBodySolver::predictDeformableMotion");
    const double geometric = zone("btDeformableMultiBodyDynamicsWorld::performGeometricCollisions") +
                             zone("performDiscreteCollisionDetection") + zone("updateSoftBodies");
    const double solve = zone("btDeformableMultiBodyDynamicsWorld::solveConstraints");
    const double integrate = zone("integrateTransforms");
    return {{"forces", (predict - collisionPrep) / total},
            {"collision", (collisionPrep + geometric) / total},
            {"solve", solve / total},
            {"integrate", integrate / total},
            {"other", std::max(0.0, 1 - (predict + geometric + solve + integrate) / total)}};
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const size_t k = v.size() / 2;
    return v.size() % 2 ? v[k] : 0.5 * (v[k - 1] + v[k]);
}

// Whole steps for at least `seconds` (at least 3); tet-steps per second.
double window(const std::function<void()>& step, int tets, double seconds) {
    long steps = 0;
    const auto t0 = Clock::now();
    while (steps < 3 || since(t0) < seconds) {
        step();
        ++steps;
    }
    return static_cast<double>(tets) * steps / since(t0);
}

struct Args {
    double seconds = 1.0;
    int rounds = 5;
    bool tiny = false, json = false;
    bool unrotated = false;  // start at the rest shape (F = I), where the polar iterations stop at once
};

Args parse(int argc, char** argv) {
    Args a;
    for (int i = 1; i < argc; ++i) {
        const std::string s = argv[i];
        if (s == "--seconds" && i + 1 < argc)
            a.seconds = std::atof(argv[++i]);
        else if (s == "--rounds" && i + 1 < argc)
            a.rounds = std::atoi(argv[++i]);
        else if (s == "--tiny")
            a.tiny = true;
        else if (s == "--json")
            a.json = true;
        else if (s == "--unrotated")
            a.unrotated = true;
        else {
            std::fprintf(stderr, "usage: %s [--seconds S] [--rounds R] [--unrotated] [--tiny] [--json]\n", argv[0]);
            std::exit(s == "--help" || s == "-h" ? 0 : 2);
        }
    }
    if (!(a.seconds > 0) || a.rounds < 1) {
        std::fprintf(stderr, "--seconds must be > 0 and --rounds >= 1\n");
        std::exit(2);
    }
    return a;
}

// A rigid rotation is a rest state of corotational elasticity: the largest node speed after
// `steps` steps from the rotated box without gravity, cutsim's and Bullet's [m/s]. What is not
// zero is the rotation's error (Bullet's comes from btPolarDecomposition's default tolerance).
std::pair<double, double> restCheck(int n, int steps) {
    Model m = boxModel(n, false);
    const Eigen::Matrix3Xd x0 = startRotation() * m.X;
    State s = makeState(m);
    s.x = x0;
    Stepper st;
    BulletBox bb(m);
    bb.setPositions(x0);
    for (int k = 0; k < steps; ++k) {
        st.step(m, s, StepOptions{Integrator::SymplecticEuler, kDt});
        bb.step();
    }
    double vc = 0, vb = 0;
    for (int i = 0; i < m.nodes(); ++i) {
        vc = std::max(vc, s.v.col(i).norm());
        const btVector3& v = bb.body->m_nodes[i].m_v;
        vb = std::max(vb, std::sqrt(v.dot(v)));
    }
    return {vc, vb};
}

}  // namespace

int main(int argc, char** argv) {
    const Args a = parse(argc, argv);
    const std::vector<int> sizes = a.tiny ? std::vector<int>{3} : std::vector<int>{6, 12, 26, 55};
    const int checkSteps = a.tiny ? 20 : 200;
    setThreads(1);
    nlohmann::json j;
    j["machine"] = machineJson();
    j["dt"] = kDt;
    j["threads"] = 1;
    j["seconds_per_window"] = a.seconds;
    j["rounds"] = a.rounds;
    j["start"] = a.unrotated ? "rest shape" : "rotated 0.3 rad about y";
    j["runs"] = nlohmann::json::array();
    const auto [restCutsim, restBullet] = restCheck(sizes.front(), checkSteps);
    j["rest_check"] = {{"tets", 6 * sizes.front() * sizes.front() * sizes.front()},
                       {"steps", checkSteps},
                       {"max_speed_cutsim", restCutsim},
                       {"max_speed_bullet", restBullet}};
    if (!a.json)
        std::printf(
            "rotated box at rest, no gravity, %d steps: largest node speed cutsim %.3g m/s, Bullet %.3g m/s\n\n",
            checkSteps, restCutsim, restBullet);
    if (!a.json)
        std::printf("%9s %8s %15s %15s %15s %15s %9s %9s %12s\n", "tets", "nodes", "cutsim double", "cutsim single",
                    "bullet", "bullet damped", "ratio", "ratio d", "max |dx| [m]");
    for (int n : sizes) {
        Model m = boxModel(n);
        const Eigen::Matrix3Xd x0 = a.unrotated ? Eigen::Matrix3Xd(m.X) : Eigen::Matrix3Xd(startRotation() * m.X);
        State s = makeState(m);
        s.x = x0;
        Stepper st;
        BulletBox bb(m);
        bb.setPositions(x0);

        // The same steps from the same start: the two should agree to rounding and the schemes'
        // small differences (the step's order of force and gravity is the same: symplectic Euler).
        const StepOptions opt{Integrator::SymplecticEuler, kDt};
        for (int k = 0; k < checkSteps; ++k) {
            st.step(m, s, opt);
            bb.step();
        }
        const double gap = bb.distance(s.x);
        double moved = 0;
        for (int i = 0; i < m.nodes(); ++i) moved = std::max(moved, (s.x.col(i) - x0.col(i)).norm());

        std::vector<double> dbl, sgl, bul, bulDamped, ratio, ratioDamped;
        auto cutsimStep = [&] { st.step(m, s, opt); };
        auto bulletStep = [&] { bb.step(); };
        for (int r = 0; r < a.rounds; ++r) {
            m.precision = ForcePrecision::Double;
            dbl.push_back(window(cutsimStep, m.elements(), a.seconds));
            m.precision = ForcePrecision::Single;
            sgl.push_back(window(cutsimStep, m.elements(), a.seconds));
            bb.elastic->setDamping(0.0, 0.0);
            bul.push_back(window(bulletStep, m.elements(), a.seconds));
            bb.elastic->setDamping(0.01, 0.01);  // btDeformableLinearElasticityForce's default
            bulDamped.push_back(window(bulletStep, m.elements(), a.seconds));
            bb.elastic->setDamping(0.0, 0.0);
            ratio.push_back(dbl.back() / bul.back());
            ratioDamped.push_back(dbl.back() / bulDamped.back());
        }
        m.precision = ForcePrecision::Double;
        const bool active = bb.body->isActive();
        const nlohmann::json stages =
            bulletStages(bb, std::max(3, static_cast<int>(a.seconds * median(bul) / m.elements())));
        j["runs"].push_back(
            {{"tets", m.elements()},
             {"nodes", m.nodes()},
             {"check_steps", checkSteps},
             {"check_max_distance", gap},
             {"check_max_displacement", moved},
             {"bullet_active", active},
             {"tet_steps_per_second",
              {{"cutsim_double", median(dbl)},
               {"cutsim_single", median(sgl)},
               {"bullet", median(bul)},
               {"bullet_damped", median(bulDamped)}}},
             {"ratio_cutsim_double_to_bullet", median(ratio)},
             {"bullet_stages", stages},
             {"ratio_cutsim_double_to_bullet_damped", median(ratioDamped)},
             {"windows",
              {{"cutsim_double", dbl}, {"cutsim_single", sgl}, {"bullet", bul}, {"bullet_damped", bulDamped}}}});
        if (!a.json)
            std::printf("%9d %8d %15.4g %15.4g %15.4g %15.4g %9.2f %9.2f %12.3g%s\n", m.elements(), m.nodes(),
                        median(dbl), median(sgl), median(bul), median(bulDamped), median(ratio), median(ratioDamped),
                        gap, active ? "" : "  (Bullet's body went to sleep)");
        if (!a.json)
            std::printf("%18s Bullet's step (damping 0): forces %.0f%%, collision structures %.0f%%, solve %.0f%%, "
                        "integrate %.0f%%, other %.0f%%\n",
                        "", 100 * stages["forces"].get<double>(), 100 * stages["collision"].get<double>(),
                        100 * stages["solve"].get<double>(), 100 * stages["integrate"].get<double>(),
                        100 * stages["other"].get<double>());
        if (!a.json) std::fflush(stdout);
    }
    setThreads(0);
    j["machine"]["load_average_end"] = loadAverage();
    if (a.json)
        std::cout << j.dump(2) << "\n";
    else
        std::printf(
            "\ntet-steps per second, median of %d windows of %.3g s each, 1 thread, dt %g s; ratio: cutsim double "
            "over\n"
            "bullet (damping 0, as cutsim), ratio d: over bullet with its default damping; max |dx|: largest node\n"
            "distance between the two after %d identical steps from the same start\n",
            a.rounds, a.seconds, kDt, checkSteps);
    return 0;
}
