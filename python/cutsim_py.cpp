// The Python module `cutsim`: the library's Simulation driven from Python (docs/python.md).
// Arrays of the state are read-only numpy views of the Simulation's own memory (no copy); they
// follow the state step by step. Before a cut reallocates that memory, the arrays that views still
// read are retired (kept, frozen at the state before the cut) and the Simulation goes on in a copy.
#include "sim/scene.hpp"
#include "sim/simulation.hpp"
#include "snapshot/scene_snapshot.hpp"
#include "util/atomic_file.hpp"
#include "util/memory.hpp"

#ifdef CUTSIM_HAVE_RENDER
#include "renderer.hpp"
#endif

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace py = pybind11;
using nlohmann::json;

namespace cutsim {
namespace {

// A Python value of the scene format (dict, list, numbers, strings, numpy arrays) as JSON.
json toJson(const py::handle& o) {
    if (o.is_none()) return nullptr;
    if (py::isinstance<py::bool_>(o)) return o.cast<bool>();
    if (py::isinstance<py::int_>(o)) return o.cast<long long>();
    if (py::isinstance<py::float_>(o)) return o.cast<double>();
    if (py::isinstance<py::str>(o)) return o.cast<std::string>();
    if (py::isinstance<py::dict>(o)) {
        json j = json::object();
        for (const auto& [k, v] : o.cast<py::dict>()) j[py::str(k).cast<std::string>()] = toJson(v);
        return j;
    }
    if (py::isinstance<py::array>(o) || py::hasattr(o, "tolist")) return toJson(o.attr("tolist")());
    if (py::isinstance<py::list>(o) || py::isinstance<py::tuple>(o)) {
        json j = json::array();
        for (const auto& v : o) j.push_back(toJson(v));
        return j;
    }
    throw InputError("scene: a value of type " + py::str(o.get_type()).cast<std::string>() +
                     " is not part of the scene format");
}

py::object toPython(const json& j) { return py::module_::import("json").attr("loads")(j.dump()); }

class SimulationError : public std::runtime_error {
    using std::runtime_error::runtime_error;
};

// The arrays the module lends to numpy views.
enum Lent : std::uint8_t { Positions, Velocities, RestPositions, ElementSteps, kLent };

// The views of one array's storage share a Loan. While the Simulation holds the storage, the Loan
// is empty; before a topology change the storage moves into it (the views keep reading it, frozen
// there) and the Simulation goes on in a copy. The last view gone frees the Loan and the storage.
struct Loan {
    Eigen::Matrix3Xd matrix;  // Positions, Velocities, RestPositions
    Eigen::VectorXd vector;   // ElementSteps
};
// A view's numpy base: the Python Simulation (owner of the arrays it still holds) and the Loan.
struct Lease {
    py::object sim;
    std::shared_ptr<Loan> loan;
};

// A Simulation with what Python adds: the views' loans, the renderer, created on the first frame.
class PySimulation {
public:
    PySimulation(const SceneDef& sc, int threads, bool renderSurface)
        : sc_(sc), sim_(sc_, Simulation::Options{threads, renderSurface}) {
        sim_.setBeforeTopologyChange([this] { retireLent(); });
    }
    PySimulation(const PySimulation&) = delete;  // the hook holds this
    PySimulation& operator=(const PySimulation&) = delete;

    Simulation& sim() { return sim_; }

    // The loan of array a's current storage, shared by all its views until a topology change.
    std::shared_ptr<Loan> loan(Lent a) {
        std::shared_ptr<Loan> l = loans_[a].lock();
        if (!l) loans_[a] = l = std::make_shared<Loan>();
        return l;
    }
    // The hook before a topology change (also inside step(), without the GIL: no Python here).
    // Arrays no view reads stay where they are; the others move into their loan, and the
    // Simulation gets an equal copy (so nothing it computes changes). The Simulation's members
    // are not const objects: writing them through the const accessors is defined.
    void retireLent() {
        for (int a = 0; a < kLent; ++a) {
            const std::shared_ptr<Loan> l = loans_[a].lock();
            if (!l) continue;
            if (a == ElementSteps) {
                auto& v = const_cast<Eigen::VectorXd&>(sim_.analyzer().estimates().r1r);
                l->vector = std::move(v);
                v = l->vector;
            } else {
                auto& m = const_cast<Eigen::Matrix3Xd&>(a == Positions    ? sim_.state().x
                                                        : a == Velocities ? sim_.state().v
                                                                          : sim_.model().X);
                l->matrix = std::move(m);
                m = l->matrix;
            }
            loans_[a].reset();
        }
    }

    // Steps n times (stops early at the scene's end); a diverged or refused step raises.
    long step(long n) {
        long done = 0;
        {
            py::gil_scoped_release release;
            while (done < n && sim_.status() == RunStatus::Running && !sim_.finished()) {
                sim_.step();
                ++done;
            }
        }
        raiseOnFailure();
        return done;
    }
    void advance(double until) {
        {
            py::gil_scoped_release release;
            sim_.advance(until);
        }
        raiseOnFailure();
    }
    void raiseOnFailure() const {
        if (sim_.status() == RunStatus::Diverged || sim_.status() == RunStatus::Refused)
            throw SimulationError(sim_.message().empty() ? runStatusName(sim_.status()) : sim_.message());
    }

    py::dict cut(const CutDef& cd, const std::string& key) {
        const CutResult r = sim_.cut(cutSurfaceOf(cd), key);
        raiseOnFailure();
        py::dict d;
        d["id"] = r.cut;
        d["crossed"] = r.crossed;
        d["split"] = r.split;
        d["new_nodes"] = r.newNodes.size();
        return d;
    }

#ifdef CUTSIM_HAVE_RENDER
    py::array_t<std::uint8_t> render(int width, int height) {
        const Capture& cap = sc_.capture;
        width = width > 0 ? width : cap.width;
        height = height > 0 ? height : cap.height;
        if (!renderer_ || renderer_->width() != width || renderer_->height() != height) {
            render::RenderOptions ro;
            ro.width = width;
            ro.height = height;
            ro.wireframe = cap.wireframe;
            ro.xray = cap.xray;
            ro.floor = cap.floor;
            ro.hud = cap.hud;
            ro.samples = cap.samples;
            renderer_ = std::make_unique<render::Renderer>(ro);
        }
        if (!snapshot_ || drawnVersion_ != sim_.topologyVersion()) {
            // a tet-mesh object before any cut draws its boundary (no surface)
            snapshot_ = std::make_unique<SceneSnapshot>(sc_, sim_.model(), sim_.analyzer().estimates().r1r, sim_.dt(),
                                                        sim_.surface());
            drawnVersion_ = sim_.topologyVersion();
            drawnDt_ = sim_.dt();
        }
        if (drawnDt_ != sim_.dt()) {  // colours and critical elements follow the step
            snapshot_->setStep(sim_.dt(), cap.criticalFactor);
            drawnDt_ = sim_.dt();
        }
        const render::Image img =
            renderer_->render(snapshot_->update(sim_.model(), sim_.state(), frameInfoOf(sim_, sim_.record().wallLoop)));
        py::array_t<std::uint8_t> out({img.height, img.width, 3});
        auto o = out.mutable_unchecked<3>();
        for (int y = 0; y < img.height; ++y)
            for (int x = 0; x < img.width; ++x)
                for (int c = 0; c < 3; ++c)
                    o(y, x, c) = img.rgba[4 * (static_cast<size_t>(y) * static_cast<size_t>(img.width) +
                                               static_cast<size_t>(x)) +
                                          static_cast<size_t>(c)];
        return out;
    }
#endif

private:
    SceneDef sc_;
    Simulation sim_;
    std::array<std::weak_ptr<Loan>, kLent> loans_;  // of the current storage, while views read it
#ifdef CUTSIM_HAVE_RENDER
    std::unique_ptr<render::Renderer> renderer_;
    std::unique_ptr<SceneSnapshot> snapshot_;
    int drawnVersion_ = -1;
    double drawnDt_ = 0;
#endif
};

// The base of a view of array a of the Python Simulation `self`: a capsule holding its Lease.
py::capsule leaseOf(const py::object& self, Lent a) {
    auto* lease = new Lease{self, self.cast<PySimulation&>().loan(a)};
    return py::capsule(lease, [](void* p) { delete static_cast<Lease*>(p); });
}
// A read-only numpy view of the Simulation's (3 x N) array a, as (N x 3): no copy.
py::array view(const py::object& self, Lent a) {
    Simulation& sim = self.cast<PySimulation&>().sim();
    const Eigen::Matrix3Xd& m = a == Positions ? sim.state().x : a == Velocities ? sim.state().v : sim.model().X;
    constexpr auto d = static_cast<py::ssize_t>(sizeof(double));
    py::array v(py::dtype::of<double>(), {static_cast<py::ssize_t>(m.cols()), py::ssize_t(3)}, {3 * d, d}, m.data(),
                leaseOf(self, a));
    py::detail::array_proxy(v.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
    return v;
}
py::array elementStepsView(const py::object& self) {
    const Eigen::VectorXd& r = self.cast<PySimulation&>().sim().analyzer().estimates().r1r;
    py::array v(py::dtype::of<double>(), {static_cast<py::ssize_t>(r.size())},
                {static_cast<py::ssize_t>(sizeof(double))}, r.data(), leaseOf(self, ElementSteps));
    py::detail::array_proxy(v.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
    return v;
}

Eigen::Vector3d vec3(const py::handle& o, const char* what) {
    const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(o);
    if (!a || a.size() != 3) throw InputError(std::string(what) + ": must be 3 numbers");
    const Eigen::Vector3d v(a.at(0), a.at(1), a.at(2));
    if (!v.allFinite()) throw InputError(std::string(what) + ": must be finite");
    return v;
}

// A rotation as a unit quaternion (w, x, y, z), normalised; finite and not zero.
Eigen::Quaterniond quaternion(const py::handle& o) {
    const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(o);
    if (!a || a.ndim() != 1 || a.size() != 4)
        throw InputError("orientation: must be a quaternion of 4 numbers (w, x, y, z)");
    Eigen::Quaterniond q(a.at(0), a.at(1), a.at(2), a.at(3));
    if (!q.coeffs().allFinite()) throw InputError("orientation: must be finite");
    if (q.norm() < 1e-12) throw InputError("orientation: must not be zero");
    return q.normalized();
}

std::unique_ptr<PySimulation> fromScene(const py::object& scene, const std::vector<std::string>& sets, int threads,
                                        bool renderSurface, const std::string& path) {
    if (py::isinstance<py::str>(scene) || py::hasattr(scene, "__fspath__")) {
        const std::string file = py::str(py::module_::import("os").attr("fspath")(scene)).cast<std::string>();
        return std::make_unique<PySimulation>(loadScene(file, sets), threads, renderSurface);
    }
    if (!py::isinstance<py::dict>(scene)) throw InputError("scene: expected a file path or a dict");
    // a dict is read as a file at `path` would be: its name in messages, relative paths from its folder
    return std::make_unique<PySimulation>(parseScene(applySets(toJson(scene), sets), path), threads, renderSurface);
}

// object.mesh given inline from numpy nodes (N x 3) and tets (M x 4, 0-based).
json inlineMesh(const py::array_t<double, py::array::c_style | py::array::forcecast>& nodes,
                const py::array_t<long long, py::array::c_style | py::array::forcecast>& tets) {
    if (nodes.ndim() != 2 || nodes.shape(1) != 3) throw InputError("nodes: must be an array of shape (N, 3)");
    if (tets.ndim() != 2 || tets.shape(1) != 4) throw InputError("tets: must be an array of shape (M, 4)");
    json n = json::array(), t = json::array();
    const auto nv = nodes.unchecked<2>();
    const auto tv = tets.unchecked<2>();
    for (py::ssize_t i = 0; i < nv.shape(0); ++i) n.push_back({nv(i, 0), nv(i, 1), nv(i, 2)});
    for (py::ssize_t e = 0; e < tv.shape(0); ++e) t.push_back({tv(e, 0), tv(e, 1), tv(e, 2), tv(e, 3)});
    return {{"nodes", std::move(n)}, {"tets", std::move(t)}};
}

// The contact world when the scene has tool i, else IndexError.
const ContactWorld& checkTool(const Simulation& sim, int i) {
    const ContactWorld* c = sim.contact();
    if (!c || i < 0 || i >= static_cast<int>(c->tools().size()))
        throw py::index_error("tool " + std::to_string(i) + ": the scene has " +
                              std::to_string(c ? c->tools().size() : 0) + " tools");
    return *c;
}

py::dict limitsDict(const StepLimits& l) {
    py::dict d;
    d["exact"] = l.exact;  // NaN: not known (not computed after a cut)
    d["certified"] = l.certified;
    d["estimate"] = l.estimate;
    return d;
}

// The exceptions the CLI reports (its messages: what it prints after "error: ").
void bindErrors(py::module_& m) {
    static py::exception<InputError> inputError(m, "InputError", PyExc_ValueError);
    static py::exception<SimulationError> simError(m, "SimulationError", PyExc_RuntimeError);
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const InputError& e) {
            inputError(e.what());
        } catch (const SimulationError& e) {
            simError(e.what());
        }
    });
}

using SimulationClass = py::class_<PySimulation>;

// The Simulation from a scene or arrays, and its steps.
void bindRuns(SimulationClass& cls) {
    cls.def(py::init(&fromScene), py::arg("scene"), py::arg("set") = std::vector<std::string>{}, py::arg("threads") = 0,
            py::arg("render_surface") = true, py::arg("path") = "scene.json",
            "A scene file (path) or a dict of the scene format; set: 'key.path=value' overrides as --set; "
            "threads 0: chosen by measuring as the CLI does")
        .def_static(
            "from_arrays",
            [](const py::array_t<double, py::array::c_style | py::array::forcecast>& nodes,
               const py::array_t<long long, py::array::c_style | py::array::forcecast>& tets, const py::dict& material,
               const py::object& scene, int threads) {
                json j = scene.is_none() ? json::object() : toJson(scene);
                j["object"] = {{"mesh", inlineMesh(nodes, tets)}};
                j["material"] = toJson(material);
                return std::make_unique<PySimulation>(parseScene(j, "arrays.json"), threads, true);
            },
            py::arg("nodes"), py::arg("tets"), py::arg("material"), py::arg("scene") = py::none(),
            py::arg("threads") = 0,
            "An object from numpy nodes (N x 3) [m] and tets (M x 4, 0-based) with a material dict "
            "(E, nu, rho, damping); scene: the other keys of the scene format (fixed, loads, ...)")
        .def("step", &PySimulation::step, py::arg("n") = 1,
             "n steps (fewer at the scene's end); returns the steps taken; raises SimulationError on divergence")
        .def("advance", &PySimulation::advance, py::arg("until"), "Steps until simulated time `until` [s]")
        .def(
            "run",
            [](PySimulation& s) {
                s.advance(s.sim().scene().duration);
                s.sim().finish();
                s.raiseOnFailure();
            },
            "Steps to the scene's duration and finishes the run (its status and final energy)")
        .def("finish", [](PySimulation& s) { s.sim().finish(); });
}

// Tools: held, their poses and the forces on them.
void bindTools(SimulationClass& cls) {
    cls.def(
           "set_tool",
           [](PySimulation& s, int i, const py::object& pos, const py::object& orientation) {
               checkTool(s.sim(), i);
               const Eigen::Vector3d p = vec3(pos, "position");
               std::optional<Eigen::Quaterniond> q;
               if (!orientation.is_none()) q = quaternion(orientation);
               s.sim().holdTool(i, p, q);
           },
           py::arg("tool"), py::arg("position"), py::arg("orientation") = py::none(),
           "Holds tool i at position [m] from now on (keyframes dropped); orientation: a quaternion "
           "(w, x, y, z), normalised, local -> world; None keeps the tool's orientation now")
        .def(
            "tool_force",
            [](PySimulation& s, int i) {
                checkTool(s.sim(), i);
                const Eigen::Vector3d f = s.sim().toolForce(i);
                return py::array_t<double>(3, f.data());
            },
            py::arg("tool") = 0,
            "Reaction force of the tissue on tool i in the last step [N] (with material.toughness, the "
            "crack front's force on a cutting blade's edge included)")
        .def(
            "cut_phase", [](PySimulation& s) { return std::string(cutPhaseName(s.sim().cutPhase())); },
            "The cutting blade's phase in the last step: idle, pressing or cutting (material.toughness)")
        .def(
            "tool_position",
            [](PySimulation& s, int i) {
                const Eigen::Vector3d p =
                    toolPose(checkTool(s.sim(), i).tools()[static_cast<size_t>(i)], s.sim().state().time).position;
                return py::array_t<double>(3, p.data());
            },
            py::arg("tool") = 0)
        .def(
            "tool_orientation",
            [](PySimulation& s, int i) {
                const Eigen::Quaterniond q =
                    toolPose(checkTool(s.sim(), i).tools()[static_cast<size_t>(i)], s.sim().state().time).orientation;
                const double wxyz[4] = {q.w(), q.x(), q.y(), q.z()};
                return py::array_t<double>(4, wxyz);
            },
            py::arg("tool") = 0, "Tool i's orientation now, a unit quaternion (w, x, y, z)");
}

// Cuts made now.
void bindCuts(SimulationClass& cls) {
    cls.def(
           "cut_plane",
           [](PySimulation& s, const py::object& point, const py::object& normal, const std::string& key) {
               CutDef cd;
               cd.point = vec3(point, "point");
               cd.normal = vec3(normal, "normal");
               if (cd.normal.norm() < 1e-12) throw InputError("normal: must not be zero");
               cd.normal.normalize();
               return s.cut(cd, key);
           },
           py::arg("point"), py::arg("normal"), py::arg("key") = "python",
           "Cuts the deformed object by the plane now (XFEM); returns the cut's figures")
        .def(
            "cut_polygon",
            [](PySimulation& s, const py::object& point, const py::object& normal,
               const py::array_t<double, py::array::c_style | py::array::forcecast>& corners, const std::string& key) {
                CutDef cd;
                cd.point = vec3(point, "point");
                cd.normal = vec3(normal, "normal");
                if (cd.normal.norm() < 1e-12) throw InputError("normal: must not be zero");
                cd.normal.normalize();
                if (corners.ndim() != 2 || corners.shape(1) != 3 || corners.shape(0) < 3)
                    throw InputError("polygon: must be an array of shape (K >= 3, 3)");
                const auto c = corners.unchecked<2>();
                for (py::ssize_t k = 0; k < c.shape(0); ++k) {
                    const Eigen::Vector3d p(c(k, 0), c(k, 1), c(k, 2));
                    if (std::abs((p - cd.point).dot(cd.normal)) > 1e-9)
                        throw InputError("polygon: its points must lie in the cut plane");
                    cd.polygon.push_back(p);
                }
                return s.cut(cd, key);
            },
            py::arg("point"), py::arg("normal"), py::arg("polygon"), py::arg("key") = "python",
            "Cuts by the convex polygon (K x 3 corners in the plane) now")
        .def(
            "cut_next_scripted", [](PySimulation& s) { return s.sim().cutNextScripted(); },
            "The scene's next scripted cut now; False when none is left");
}

// The state's arrays: views that follow the steps, and copies.
void bindArrays(SimulationClass& cls) {
    cls.def_property_readonly(
           "positions", [](const py::object& self) { return view(self, Positions); },
           "Node positions (N x 3) [m]: a read-only view (no copy) that follows the steps; a view taken "
           "before a cut keeps the values of just before it (take the property again for the new nodes)")
        .def_property_readonly(
            "velocities", [](const py::object& self) { return view(self, Velocities); },
            "Node velocities (N x 3) [m/s]: a read-only view as positions (frozen at a cut)")
        .def_property_readonly(
            "rest_positions", [](const py::object& self) { return view(self, RestPositions); },
            "Rest positions (N x 3) [m]: a read-only view as positions (frozen at a cut)")
        .def_property_readonly("tets",
                               [](PySimulation& s) {
                                   const auto& t = s.sim().model().tets;
                                   py::array_t<int> a({t.cols(), Eigen::Index(4)});
                                   std::copy(t.data(), t.data() + t.size(), a.mutable_data());
                                   return a;
                               })
        .def_property_readonly(
            "input_nodes",
            [](PySimulation& s) {
                py::array_t<int> a(s.sim().model().nodes());
                for (int n = 0; n < s.sim().model().nodes(); ++n) a.mutable_at(n) = s.sim().inputNode(n);
                return a;
            },
            "Each node's index in the mesh file (N): a scene's mesh file is put in spatial order on load "
            "(object.reorder), so row i of positions is node input_nodes[i] of the file; nodes a cut made "
            "give the node they were copied from")
        .def_property_readonly(
            "input_elements",
            [](PySimulation& s) {
                py::array_t<int> a(s.sim().model().elements());
                for (int e = 0; e < s.sim().model().elements(); ++e) a.mutable_at(e) = s.sim().inputElement(e);
                return a;
            },
            "Each element's index in the mesh file (M), as input_nodes")
        .def_property_readonly(
            "element_steps", [](const py::object& self) { return elementStepsView(self); },
            "Each element's stable step estimate (reduced one ring) [s]: a read-only view as positions "
            "(frozen at a cut)")
        .def_property_readonly(
            "critical_elements",
            [](PySimulation& s) {
                const auto& r1r = s.sim().analyzer().estimates().r1r;
                const double bound = s.sim().scene().capture.criticalFactor * s.sim().dt();
                std::vector<int> out;
                for (Eigen::Index e = 0; e < r1r.size(); ++e)
                    if (r1r(e) < bound) out.push_back(static_cast<int>(e));
                return py::array_t<int>(static_cast<py::ssize_t>(out.size()), out.data());
            },
            "Elements whose estimate is under capture.critical_factor times dt");
}

// The run's limits, figures, names, hash and report.
void bindFigures(SimulationClass& cls) {
    cls.def_property_readonly(
           "limits", [](PySimulation& s) { return limitsDict(s.sim().limits()); },
           "Current stable limits {exact, certified, estimate} [s]; exact NaN: unknown")
        .def_property_readonly("initial_limits", [](PySimulation& s) { return limitsDict(s.sim().initialLimits()); })
        .def_property_readonly("dt", [](PySimulation& s) { return s.sim().dt(); })
        .def_property_readonly("time", [](PySimulation& s) { return s.sim().state().time; })
        .def_property_readonly("steps", [](PySimulation& s) { return s.sim().state().steps; })
        .def_property_readonly("duration", [](PySimulation& s) { return s.sim().scene().duration; })
        .def_property_readonly("finished", [](PySimulation& s) { return s.sim().finished(); })
        .def_property_readonly("status", [](PySimulation& s) { return runStatusName(s.sim().status()); })
        .def_property_readonly("message", [](PySimulation& s) { return s.sim().message(); })
        .def_property_readonly("nodes", [](PySimulation& s) { return s.sim().model().nodes(); })
        .def_property_readonly("elements", [](PySimulation& s) { return s.sim().model().elements(); })
        .def_property_readonly("cuts", [](PySimulation& s) { return s.sim().record().cutsMade; })
        .def_property_readonly("threads", [](PySimulation& s) { return s.sim().threads(); })
        .def_property_readonly("tool_names",
                               [](PySimulation& s) {
                                   std::vector<std::string> names;
                                   for (const auto& t : s.sim().scene().tools) names.push_back(t.name);
                                   return names;
                               })
        .def(
            "state_hash",
            [](PySimulation& s) {
                char h[20];
                std::snprintf(h, sizeof h, "%016llx", static_cast<unsigned long long>(s.sim().stateHash()));
                return std::string(h);
            },
            "FNV-1a of positions and velocities, as report.json's state_hash")
        .def(
            "report",
            [](PySimulation& s, const std::optional<std::string>& path) {
                const json r = s.sim().report();
                if (path) writeFileAtomic(*path, r.dump(2) + "\n");
                return toPython(r);
            },
            py::arg("path") = py::none(), "The run's report (report.json) as a dict, written to path when given");
}

#ifdef CUTSIM_HAVE_RENDER
// The frame now, offscreen.
void bindRender(SimulationClass& cls) {
    cls.def("render", &PySimulation::render, py::arg("width") = 0, py::arg("height") = 0,
            "The frame now, offscreen, as an (H x W x 3) uint8 image; size 0: the scene's capture size");
}
#endif

}  // namespace
}  // namespace cutsim

PYBIND11_MODULE(cutsim, m) {
    using namespace cutsim;
    mapLargeArrays();  // arrays a cut grows are remapped, not copied (util/memory.hpp)
    m.doc() = "cutsim: explicit FEM soft-tissue cutting (docs/python.md).\n\n"
              "Simulation.positions, velocities, rest_positions and element_steps are read-only numpy views of "
              "the simulation's memory (no copy) that follow the steps. A cut (cut_plane, cut_polygon, "
              "cut_next_scripted, or a scripted cut or blade sweep inside step) keeps the memory of views taken "
              "before it alive, frozen at the values of just before the cut; take the property again for the "
              "new state (its new node and element count).";
    bindErrors(m);
    SimulationClass cls(m, "Simulation");
    bindRuns(cls);
    bindTools(cls);
    bindCuts(cls);
    bindArrays(cls);
    bindFigures(cls);
#ifdef CUTSIM_HAVE_RENDER
    bindRender(cls);
#endif
}
