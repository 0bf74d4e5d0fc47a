#include "sim/scene.hpp"

#include "sim/json_reader.hpp"
#include "mesh/io.hpp"
#include "mesh/io_detail.hpp"

#include "cut/xfem.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>

namespace cutsim {

namespace fs = std::filesystem;
using nlohmann::json;

double Profile::at(double t) const {
    switch (kind) {
    case Kind::Constant: return t >= start ? 1.0 : 0.0;
    case Kind::Ramp:
        if (t <= start) return 0.0;
        if (t >= end) return 1.0;
        return (t - start) / (end - start);
    case Kind::Sine: return t >= start && t <= end ? std::sin(2 * std::numbers::pi * (t - start) / period) : 0.0;
    case Kind::Pulse: return t >= start && t <= end ? 1.0 : 0.0;
    }
    return 0.0;
}

namespace {

// Why the file at p cannot be read, or "" when it exists (a name too long, a loop of links or a
// folder without access are refused here, not thrown by std::filesystem later).
std::string missingFile(const fs::path& p) {
    std::error_code ec;
    if (fs::exists(p, ec)) return "";
    return (ec ? "cannot read " + p.string() + ": " + ec.message() : "file not found: " + p.string());
}

// The file named by r's key, relative to the scene's folder dir, as a normal path; the key fails
// when the file is missing.
std::string existingPath(ObjectReader& r, const std::string& key, const std::string& dir) {
    fs::path p(r.requiredString(key));
    if (p.empty()) r.fail(key, "is empty: give the path of a file");
    if (p.is_relative()) p = fs::path(dir) / p;
    if (const std::string why = missingFile(p); !why.empty()) r.fail(key, why);
    return p.lexically_normal().string();
}

Region readRegion(ObjectReader& r) {
    Region g;
    g.path = r.path();
    g.file = r.file();
    int kinds = 0;
    if (r.has("box")) {
        ObjectReader b = r.object("box");
        g.kind = Region::Kind::Box;
        g.min = b.requiredVec3("min");
        g.max = b.requiredVec3("max");
        if ((g.max.array() < g.min.array()).any()) b.fail("max", "must be >= min in every axis");
        b.finish();
        ++kinds;
    }
    if (r.has("plane")) {
        ObjectReader p = r.object("plane");
        g.kind = Region::Kind::Plane;
        g.point = p.requiredVec3("point");
        g.normal = p.requiredUnitVec3("normal");
        g.distance = p.number("distance", 1e-3, 0, 1e300);
        p.finish();
        ++kinds;
    }
    if (r.has("sphere")) {
        ObjectReader s = r.object("sphere");
        g.kind = Region::Kind::Sphere;
        g.point = s.requiredVec3("center");
        g.distance = s.requiredNumber("radius", 0, 1e300);
        if (!(g.distance > 0)) s.fail("radius", "must be > 0");
        s.finish();
        ++kinds;
    }
    if (r.has("nodes")) {
        g.kind = Region::Kind::Nodes;
        g.nodes = r.intList("nodes");
        ++kinds;
    }
    if (kinds != 1) throw InputError(r.file() + ": " + r.path() + ": give exactly one of box, plane, sphere, nodes");
    return g;
}

Profile readProfile(ObjectReader& r) {
    Profile p;
    const std::string k = r.string("type", "constant", {"constant", "ramp", "sine", "pulse"});
    p.kind = k == "ramp"    ? Profile::Kind::Ramp
             : k == "sine"  ? Profile::Kind::Sine
             : k == "pulse" ? Profile::Kind::Pulse
                            : Profile::Kind::Constant;
    p.start = r.number("start", 0, 0);
    p.end = r.number("end", p.kind == Profile::Kind::Ramp ? p.start + 1 : 1e300, p.start);
    if (p.kind == Profile::Kind::Ramp && !(p.end > p.start)) r.fail("end", "must be > start for a ramp");
    p.period = r.number("period", 1, 0, 1e300, true);
    r.finish();
    return p;
}

// A tool: shape, path of keyframes, penalty parameters (docs/scene-format.md, "tools").
ToolDef readTool(ObjectReader& r, const std::string& dir, int index) {
    ToolDef t;
    t.name = r.string("name", "tool" + std::to_string(index));
    const std::string kind = r.string("kind", "sphere", {"sphere", "capsule", "blade", "grasper", "hull"});
    t.kind = kind == "capsule"   ? ToolDef::Kind::Capsule
             : kind == "blade"   ? ToolDef::Kind::Blade
             : kind == "grasper" ? ToolDef::Kind::Grasper
             : kind == "hull"    ? ToolDef::Kind::Hull
                                 : ToolDef::Kind::Sphere;
    if (t.kind == ToolDef::Kind::Sphere || t.kind == ToolDef::Kind::Capsule) {
        t.radius = r.requiredNumber("radius", 0, 1e3);
        if (!(t.radius > 0)) r.fail("radius", "must be > 0");
    }
    if (t.kind == ToolDef::Kind::Capsule) t.length = r.number("length", 2 * t.radius, 0, 1e3);
    if (t.kind == ToolDef::Kind::Blade || t.kind == ToolDef::Kind::Grasper) {
        t.size = r.requiredVec3("size");
        if ((t.size.array() <= 0).any()) r.fail("size", "must be positive in every axis");
    }
    if (t.kind == ToolDef::Kind::Hull) {
        const std::string path = existingPath(r, "obj", dir);
        const double scale = r.number("scale", 1, 0, 1e300, true);
        t.hull = readSurfaceMesh(path, scale, r.where("scale")).V;
        if (t.hull.cols() < 4) r.fail("obj", "needs at least 4 vertices for a convex hull");
        const Eigen::Vector3d ext = t.hull.rowwise().maxCoeff() - t.hull.rowwise().minCoeff();
        if ((ext.array() <= 0).any()) r.fail("obj", "is flat: a hull needs volume");
    }
    t.stiffness = r.number("stiffness", 0, 0, 1e300);
    t.damping = r.number("damping", -1, 0, 1e300);  // absent: -1, automatic
    t.friction = r.number("friction", t.friction, 0, 10);
    const double d2r = std::numbers::pi / 180.0;
    for (auto& k : r.array("keyframes")) {
        ToolKey key;
        key.time = k.number("time", 0, 0);
        key.pose.position = k.requiredVec3("position");
        if (k.has("rotation_deg") && k.has("quaternion"))
            k.fail("quaternion", "give at most one of rotation_deg and quaternion");
        if (k.has("rotation_deg")) {
            const Eigen::Vector3d a =
                k.vec3("rotation_deg", Eigen::Vector3d::Zero()) * d2r;  // XYZ, as object.rotate_deg
            key.pose.orientation = Eigen::AngleAxisd(a.z(), Eigen::Vector3d::UnitZ()) *
                                   Eigen::AngleAxisd(a.y(), Eigen::Vector3d::UnitY()) *
                                   Eigen::AngleAxisd(a.x(), Eigen::Vector3d::UnitX());
        }
        if (k.has("quaternion")) {
            const json& q = k.raw("quaternion");
            bool ok = q.is_array() && q.size() == 4;
            for (size_t i = 0; ok && i < 4; ++i) ok = q[i].is_number() && std::isfinite(q[i].get<double>());
            if (!ok) k.fail("quaternion", "must be an array of 4 finite numbers [w, x, y, z]");
            Eigen::Vector4d w(q[0].get<double>(), q[1].get<double>(), q[2].get<double>(), q[3].get<double>());
            const double big = w.cwiseAbs().maxCoeff();  // scaled first: the norm of 1e200 overflows
            if (!(big > 1e-300)) k.fail("quaternion", "must not be zero");
            // a unit quaternion as written (a recorded take) is kept bitwise: normalising again can move its last bits
            if (std::abs(w.norm() - 1) > 4e-16) w = (w / big).normalized();
            key.pose.orientation = Eigen::Quaterniond(w(0), w(1), w(2), w(3));
            k.touch("quaternion");
        }
        key.opening = t.kind == ToolDef::Kind::Grasper ? k.number("opening", 0, 0, 1e3) : 0.0;
        k.finish();
        if (!t.keys.empty() && key.time < t.keys.back().time) k.fail("time", "keyframes must be in time order");
        t.keys.push_back(key);
    }
    if (t.keys.empty()) r.fail("keyframes", "is required (at least one keyframe)");
    return t;
}

// A static collider: a plane (point, normal), a box (center, size, rotation_deg), a sphere (center,
// radius) or a convex mesh (obj, scale, center) (docs/scene-format.md, "colliders").
ColliderDef readCollider(ObjectReader& r, const std::string& dir, int index) {
    ColliderDef c;
    c.name = r.string("name", "collider" + std::to_string(index));
    const std::string kind = r.requiredString("kind");
    if (kind != "plane" && kind != "box" && kind != "sphere" && kind != "mesh")
        r.fail("kind", "must be one of plane, box, sphere, mesh; got \"" + kind + "\"");
    c.friction = r.number("friction", c.friction, 0, 10);
    const double d2r = std::numbers::pi / 180.0;
    if (kind == "plane") {
        c.kind = ColliderDef::Kind::Plane;
        c.pose.position = r.requiredVec3("point");
        c.pose.orientation = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), r.requiredUnitVec3("normal"));
        return c;
    }
    c.pose.position = r.vec3("center", Eigen::Vector3d::Zero());
    const Eigen::Vector3d a = r.vec3("rotation_deg", Eigen::Vector3d::Zero()) * d2r;  // XYZ, as tools
    c.pose.orientation = Eigen::AngleAxisd(a.z(), Eigen::Vector3d::UnitZ()) *
                         Eigen::AngleAxisd(a.y(), Eigen::Vector3d::UnitY()) *
                         Eigen::AngleAxisd(a.x(), Eigen::Vector3d::UnitX());
    if (kind == "box") {
        c.kind = ColliderDef::Kind::Box;
        c.size = 0.5 * r.requiredVec3("size");
        if ((c.size.array() <= 0).any()) r.fail("size", "must be positive in every axis");
    } else if (kind == "sphere") {
        c.kind = ColliderDef::Kind::Sphere;
        c.size.x() = r.requiredNumber("radius", 0, 1e3);
        if (!(c.size.x() > 0)) r.fail("radius", "must be > 0");
    } else {
        c.kind = ColliderDef::Kind::Mesh;
        const std::string path = existingPath(r, "obj", dir);
        const double scale = r.number("scale", 1, 0, 1e300, true);
        const SurfaceMesh sm = readSurfaceMesh(path, scale, r.where("scale"));
        c.vertices = sm.V;
        c.triangles = sm.F;
        if (c.vertices.cols() < 4) r.fail("obj", "needs at least 4 vertices (a mesh collider is its convex hull)");
        const Eigen::Vector3d ext = c.vertices.rowwise().maxCoeff() - c.vertices.rowwise().minCoeff();
        if ((ext.array() <= 0).any()) r.fail("obj", "is flat: a collider needs volume");
    }
    return c;
}

// Deeper nesting than any scene needs is refused while parsing: copies and comparisons of a
// nlohmann document recurse, so 200,000 nested arrays would overflow the stack later.
constexpr int kMaxJsonDepth = 64;

// Parses `text`; a syntax error, a number out of double range or nesting deeper than
// kMaxJsonDepth names `where` and, for a file, the line.
json parseJson(const std::string& text, const std::string& where, bool isFile) {
    auto lineOf = [&](size_t byte) {
        long line = 1;
        for (size_t i = 0; i < std::min(text.size(), byte); ++i) line += text[i] == '\n';
        return isFile ? line : 0;
    };
    const json::parser_callback_t limit = [&](int depth, json::parse_event_t ev, json&) {
        if (depth > kMaxJsonDepth &&
            (ev == json::parse_event_t::object_start || ev == json::parse_event_t::array_start))
            throw std::length_error("nested");
        return true;
    };
    try {
        return json::parse(text, limit);
    } catch (const json::parse_error& e) {
        throw InputError(where, lineOf(e.byte), std::string("invalid JSON: ") + e.what());
    } catch (const json::out_of_range& e) {
        // 406: a number beyond double range, e.g. 1e400; nlohmann gives no position
        std::string why = e.what();
        const auto q = why.find('\'');
        size_t at = std::string::npos;
        if (q != std::string::npos) at = text.find(why.substr(q + 1, why.find('\'', q + 1) - q - 1));
        throw InputError(where, at == std::string::npos ? 0 : lineOf(at),
                         "invalid JSON: a number beyond the range of a double (" + why.substr(why.find(' ') + 1) + ")");
    } catch (const std::length_error&) {
        throw InputError(where, 0, "invalid JSON: nested deeper than " + std::to_string(kMaxJsonDepth) + " levels");
    }
}

// object.mesh as {"nodes": [[x, y, z], ...], "tets": [[a, b, c, d], ...]} (0-based), as the Python
// bindings pass numpy arrays.
TetMesh readInlineMesh(ObjectReader r) {
    const std::string source = r.file() + ": object.mesh";
    auto rows = [&](const char* key, size_t width) -> const json& {
        if (!r.has(key)) r.fail(key, "is required");
        const json& a = r.raw(key);
        r.touch(key);
        if (!a.is_array() || a.empty()) r.fail(key, "must be a non-empty array");
        for (const json& row : a)
            if (!row.is_array() || row.size() != width ||
                !std::all_of(row.begin(), row.end(), [](const json& v) { return v.is_number(); }))
                r.fail(key, "every entry must be " + std::to_string(width) + " numbers");
        return a;
    };
    const json& nodes = rows("nodes", 3);
    const json& tets = rows("tets", 4);
    detail::RawTets raw;
    raw.xyz.reserve(3 * nodes.size());
    for (const json& row : nodes)
        for (const json& v : row) raw.xyz.push_back(v.get<double>());
    raw.tets.reserve(4 * tets.size());
    const long n = static_cast<long>(nodes.size());
    for (size_t e = 0; e < tets.size(); ++e)
        for (const json& v : tets[e]) {
            if (!v.is_number_integer() || v.get<long>() < 0 || v.get<long>() >= n)
                r.fail("tets", "tet " + std::to_string(e) + ": node index must be an integer in [0, " +
                                   std::to_string(n) + ")");
            raw.tets.push_back(v.get<int>());
        }
    r.finish();
    // the checks of every mesh file: coordinate range, zero-volume, flat and inverted tets
    return detail::finishTetMesh(source, std::move(raw), ReadOptions{}, nullptr);
}

void setPath(json& j, const std::string& assignment) {
    const auto eq = assignment.find('=');
    if (eq == std::string::npos || eq == 0) throw InputError("--set " + assignment + ": expected key.path=value");
    const std::string key = assignment.substr(0, eq), text = assignment.substr(eq + 1);
    json value;
    if (!json::accept(text))
        value = text;  // a bare word is a string
    else
        value = parseJson(text, "--set " + key, false);
    json* node = &j;
    size_t pos = 0;
    while (true) {
        const size_t dot = key.find('.', pos);
        const std::string part = key.substr(pos, dot == std::string::npos ? std::string::npos : dot - pos);
        if (part.empty()) throw InputError("--set " + assignment + ": empty key in path");
        // an array element by its index (tools.0.keyframes.2.position.1), never appended
        if (node->is_array()) {
            size_t idx = 0;
            const auto [end, ec] = std::from_chars(part.data(), part.data() + part.size(), idx);
            if (ec != std::errc() || end != part.data() + part.size() || idx >= node->size())
                throw InputError("--set " + assignment + ": '" + part + "' is not an index of an array of " +
                                 std::to_string(node->size()));
            node = &(*node)[idx];
            if (dot == std::string::npos) {
                *node = value;
                return;
            }
            pos = dot + 1;
            continue;
        }
        if (!node->is_object()) throw InputError("--set " + assignment + ": '" + part + "' is inside a non-object");
        if (dot == std::string::npos) {
            (*node)[part] = value;
            return;
        }
        node = &(*node)[part];
        if (node->is_null()) *node = json::object();
        pos = dot + 1;
    }
}

}  // namespace

std::vector<int> selectNodes(const Region& r, const Eigen::Matrix3Xd& X) {
    std::vector<int> out;
    const int n = static_cast<int>(X.cols());
    if (r.kind == Region::Kind::Nodes) {
        for (int i : r.nodes) {
            if (i >= n)
                throw InputError(r.file + ": " + r.path + ".nodes: node " + std::to_string(i) +
                                 " does not exist (mesh has " + std::to_string(n) + ")");
            out.push_back(i);
        }
        return out;
    }
    for (int i = 0; i < n; ++i) {
        const Eigen::Vector3d x = X.col(i);
        bool in = false;
        switch (r.kind) {
        case Region::Kind::Box: in = (x.array() >= r.min.array()).all() && (x.array() <= r.max.array()).all(); break;
        case Region::Kind::Plane: in = std::abs(r.normal.dot(x - r.point)) <= r.distance; break;
        case Region::Kind::Sphere: in = (x - r.point).norm() <= r.distance; break;
        case Region::Kind::Nodes: break;
        }
        if (in) out.push_back(i);
    }
    return out;
}

const char* precisionConflict(Integrator integ, ForcePrecision precision) {
    // a backward-Euler step spends under 2% of its time in the force kernel: nothing to gain
    return precision == ForcePrecision::Single && integ == Integrator::BackwardEuler
               ? "single applies to the explicit schemes only (backward Euler spends under 2% of a step in the forces)"
               : nullptr;
}

namespace {

// object: the mesh, box, surface or tetra, and how it is placed and improved.
void readObjectSection(ObjectReader& root, SceneDef& s) {
    ObjectReader o = root.object("object");
    if (int(o.has("mesh")) + int(o.has("box")) + int(o.has("surface")) + int(o.has("tetra")) != 1)
        o.fail("mesh", "give exactly one of mesh (a tet mesh file), box, surface and tetra");
    if (o.has("mesh") && o.raw("mesh").is_object()) {
        s.meshData = std::make_shared<const TetMesh>(readInlineMesh(o.object("mesh")));
    } else if (o.has("mesh")) {
        s.mesh = existingPath(o, "mesh", s.dir);
    } else if (o.has("tetra")) {
        // A surface filled with tets at load (`cutsim tetra`), cached by content.
        ObjectReader te = o.object("tetra");
        s.tetraSurface = existingPath(te, "surface", s.dir);
        if (!te.has("size")) te.fail("size", "required: the target edge length [m]");
        s.tetraSize = te.number("size", 0, 0, 1e300, true);
        s.tetraImprove = te.boolean("improve", true);
        const std::string mesher = te.string("mesher", "auto", {"auto", "gmsh", "tetgen"});
        s.tetraMesher = mesher == "gmsh" ? Mesher::Gmsh : mesher == "tetgen" ? Mesher::TetGen : Mesher::Auto;
        te.finish();
    } else if (o.has("surface")) {
        // Mesh intersection (thesis ch. 6): a surface embedded in a regular lattice.
        ObjectReader su = o.object("surface");
        s.surface = existingPath(su, "path", s.dir);
        if (su.has("cells") == su.has("h")) su.fail("cells", "give exactly one of cells and h");
        s.surfaceCells = su.has("cells") ? su.integer("cells", 16, 1, 1000) : 0;
        s.surfaceH = su.has("h") ? su.number("h", 0, 0, 1e300, true) : 0;
        s.surfaceFixOutside = su.boolean("fix_outside", false);
        s.surfaceKeepStep = su.boolean("keep_step", true);
        su.finish();
    } else {
        ObjectReader b = o.object("box");
        s.boxSize = b.requiredVec3("size");
        if ((s.boxSize.array() < kMinExtent).any() || (s.boxSize.array() > kMaxCoordinate).any())
            b.fail("size", "must lie within [1e-6, 1e6] m in every axis");
        const Eigen::Vector3d cells = b.requiredVec3("cells");
        for (int k = 0; k < 3; ++k)
            if (cells(k) < 1 || cells(k) > 1000 || cells(k) != std::floor(cells(k)))
                b.fail("cells", "must be 3 integers in [1, 1000]");
        s.boxCells = cells.cast<int>();
        if (static_cast<double>(s.boxCells.prod()) * 6 > 2e7) b.fail("cells", "more than 2e7 tets");
        b.finish();
    }
    s.scale = o.number("scale", 1, 0, 1e9, true);
    // a box or an inline mesh is known here: the coordinate range after scaling is the scale's
    // limit (a mesh file's is checked where it is read, naming this key too)
    if (s.meshData)
        detail::checkCoordinateRange(s.meshData->source, s.scale * s.meshData->X, o.where("scale"), s.scale);
    const Eigen::Vector3d box = s.scale * s.boxSize;
    if (o.has("box") && ((box.array() < kMinExtent).any() || (box.array() > kMaxCoordinate).any())) {
        char why[160];
        std::snprintf(why, sizeof why,
                      "%g makes the box %g x %g x %g m; it must lie within [1e-6, 1e6] m in every axis", s.scale,
                      box.x(), box.y(), box.z());
        o.fail("scale", why);
    }
    s.translate = o.vec3("translate", s.translate);
    s.rotateDeg = o.vec3("rotate_deg", s.rotateDeg);
    s.reorient = o.boolean("reorient", false);
    if (o.has("reorder") && s.mesh.empty())
        o.fail("reorder", "applies to a tet mesh file (object.mesh); boxes, inline meshes and surfaces keep "
                          "their order");
    s.reorder = o.boolean("reorder", true);
    if (o.has("improve")) {
        if (o.has("surface")) o.fail("improve", "applies to a tet mesh object (mesh or box), not to surface");
        if (o.has("tetra")) o.fail("improve", "a tetra mesh is improved when built (object.tetra.improve)");
        if (o.raw("improve").is_boolean()) {
            s.improve = o.boolean("improve", false);
        } else {
            ObjectReader im = o.object("improve");
            s.improve = true;
            ImproveOptions& io = s.improveOptions;
            io.maxSeconds = im.number("max_seconds", io.maxSeconds, 0, 1e6, true);
            io.maxRounds = static_cast<int>(im.integer("rounds", io.maxRounds, 1, 100000));
            io.featureAngleDeg = im.number("feature_angle", io.featureAngleDeg, 0, 180);
            io.maxVolumeChange = im.number("max_volume_change", io.maxVolumeChange, 0, 0.5);
            io.maxBoundaryDistance = im.number("max_boundary_distance", io.maxBoundaryDistance, 0, 0.5);
            io.moveBoundary = im.boolean("move_boundary", io.moveBoundary);
            im.finish();
        }
    }
    if (o.has("visual")) {
        // A fine surface drawn in place of the tet boundary or of an MI object's own (touched)
        // surface, riding the elements (embed/visual.hpp).
        s.visualScale = s.scale;
        if (o.raw("visual").is_object()) {
            ObjectReader v = o.object("visual");
            s.visual = existingPath(v, "path", s.dir);
            s.visualScale = v.number("scale", s.scale, 0, 1e9, true);
            v.finish();
        } else {
            s.visual = existingPath(o, "visual", s.dir);
        }
    }
    s.anySize = o.boolean("any_size", false);
    const std::string element = o.string("element", "corotational", {"corotational", "linear", "hybrid"});
    s.element = element == "linear" ? ElementModel::Linear : ElementModel::Corotational;
    s.hybrid = element == "hybrid";
    s.hybridThreshold = o.number("hybrid_threshold", s.hybridThreshold, 1, 10);
    s.matchStiffness = o.number("match_stiffness", s.matchStiffness, 0, 1, true);
    o.finish();
}

// integrator: the scheme, the step policy, stretch limiting, the solver and precision.
void readIntegratorSection(ObjectReader in, SceneDef& s) {
    s.integrator = parseIntegrator(in.string("scheme", "symplectic_euler",
                                             {"symplectic_euler", "central_difference", "newmark", "backward_euler"}));
    if (in.has("dt")) {
        ObjectReader d = in.object("dt");
        const std::string mode = d.string("mode", "fraction", {"fixed", "fraction"});
        if (mode == "fixed") {
            s.dt.fixed = true;
            s.dt.value = d.number("value", 0, 0, 10, true);
            if (!d.has("value")) d.fail("value", "is required for mode fixed");
        } else {
            s.dt.fixed = false;
            s.dt.of = parseLimitOf(d.string("of", "exact", {"exact", "certified", "estimate"}));
            s.dt.fraction = d.number("fraction", 0.9, 0, 100, true);
        }
        s.dt.onLimit = parseOnLimit(d.string("on_limit", "refuse", {"refuse", "clamp", "damp"}));
        d.finish();
    }
    s.minStretch = in.number("min_stretch", 0, 0, 0.9);
    s.maxSteps = in.number("max_steps", s.maxSteps, 1, 1e15);
    s.implicitSolver = parseImplicitSolver(in.string("solver", "direct", {"direct", "cg"}));
    if (in.has("solver") && s.integrator != Integrator::BackwardEuler)
        in.fail("solver", "applies to scheme backward_euler only");
    s.precision = in.string("precision", "double", {"double", "single"}) == "single" ? ForcePrecision::Single
                                                                                     : ForcePrecision::Double;
    if (const char* why = precisionConflict(s.integrator, s.precision)) in.fail("precision", why);
    in.finish();
}

// cutting: lumping, the after-cut response, scripted cuts and the baselines to compare.
void readCuttingSection(ObjectReader c, SceneDef& s) {
    s.cutting.lumping = parseLumping(c.string("lumping", "enrichment", {"row_sum", "weighted_diagonal", "enrichment"}));
    s.cutting.minFraction = c.number("min_fraction", CutOptions{}.minFraction, 0, 0.5);
    if (c.has("exact_after_cut") && c.raw("exact_after_cut").is_string()) {
        s.cutting.exactAtStrokeEnd = c.string("exact_after_cut", "stroke_end", {"stroke_end"}) == "stroke_end";
        s.cutting.exactAfterCut = true;
    } else if (c.has("exact_after_cut")) {
        s.cutting.exactAfterCut = c.boolean("exact_after_cut", true);
        s.cutting.exactAtStrokeEnd = false;
    }
    s.cutting.stepFloor = c.number("step_floor", Cutting{}.stepFloor, 0, 1);
    s.cutting.floorHybrid = c.string("floor_method", "mass", {"mass", "hybrid"}) == "hybrid";
    const Cutting dflt;
    s.cutting.mergeDebris = c.boolean("merge_debris", dflt.mergeDebris);
    s.cutting.relaxIterations = c.integer("relax_iterations", dflt.relaxIterations, 0, 100);
    s.cutting.lightShare = c.number("light_share", dflt.lightShare, 0, 0.5);
    s.cutting.bladeSlot = c.boolean("blade_slot", dflt.bladeSlot);
    if (c.has("compare")) {
        const json& cmp = c.raw("compare");
        c.touch("compare");
        const char* what = "must be an array of \"subdivision\", \"subdivision_improve\" and \"remesh\"";
        if (!cmp.is_array()) c.fail("compare", what);
        for (const auto& m : cmp) {
            if (!m.is_string() || (m != "subdivision" && m != "remesh" && m != "subdivision_improve"))
                c.fail("compare", what);
            s.cutting.compare.push_back(m.get<std::string>());
        }
    }
    for (auto& k : c.array("cuts")) {
        CutDef cd;
        cd.path = k.path();
        cd.time = k.number("time", 0, 0);
        cd.point = k.requiredVec3("point");
        cd.normal = k.requiredUnitVec3("normal");
        if (k.has("polygon")) {
            const json& poly = k.raw("polygon");
            k.touch("polygon");
            if (!poly.is_array() || poly.size() < 3)
                k.fail("polygon", "must be an array of at least 3 points [x, y, z]");
            for (const auto& q : poly) {
                if (!q.is_array() || q.size() != 3 || !q[0].is_number() || !q[1].is_number() || !q[2].is_number())
                    k.fail("polygon", "must be an array of at least 3 points [x, y, z]");
                const Eigen::Vector3d p(q[0].get<double>(), q[1].get<double>(), q[2].get<double>());
                if (std::abs(cd.normal.dot(p - cd.point)) > 1e-6 * std::max(1.0, (p - cd.point).norm()))
                    k.fail("polygon", "its points must lie in the cut plane");
                cd.polygon.push_back(p);
            }
        }
        k.finish();
        if (!s.cutting.cuts.empty() && cd.time < s.cutting.cuts.back().time)
            k.fail("time", "cuts must be in time order");
        s.cutting.cuts.push_back(cd);
    }
    for (const CutDef& cd : s.cutting.cuts)
        if (!s.cutting.compare.empty() && !cd.polygon.empty())
            c.fail("compare", "the baselines cut whole planes; " + cd.path + " is bounded by a polygon");
    c.finish();
}

// capture: frames, video, colour map and screenshot-test settings.
void readCaptureSection(ObjectReader c, SceneDef& s) {
    s.capture.enabled = c.boolean("enabled", true);
    s.capture.fps = c.number("fps", 30, 0, 1e5, true);
    s.capture.playbackFps = c.number("playback_fps", 0, 0, 1000);
    s.capture.width = c.integer("width", 1280, 16, 8192);
    s.capture.height = c.integer("height", 720, 16, 8192);
    s.capture.samples = c.integer("samples", 1, 1, 16);
    s.capture.colormap = c.string("colormap", "timestep", {"timestep", "displacement", "stress", "none"});
    s.capture.video = c.boolean("video", true);
    s.capture.pngEvery = c.integer("png_every", 1, 0, 1000000);
    s.capture.hud = c.boolean("hud", true);
    s.capture.wireframe = c.boolean("wireframe", false);
    s.capture.xray = c.boolean("xray", true);
    s.capture.criticalFactor = c.number("critical_factor", 1.1, 0, 100, true);
    s.capture.answeredSeconds = c.number("answered_seconds", 0.5, 0, 1e6);
    if (c.has("range")) {
        const json& r = c.raw("range");
        if (!r.is_array() || r.size() != 2 || !r[0].is_number() || !r[1].is_number() ||
            !(r[0].get<double>() < r[1].get<double>()) || !std::isfinite(r[0].get<double>()) ||
            !std::isfinite(r[1].get<double>()))
            c.fail("range", "must be [min, max] with min < max, in the colour map's unit, got " + r.dump());
        s.capture.rangeMin = r[0].get<double>();
        s.capture.rangeMax = r[1].get<double>();
        c.touch("range");
    }
    s.capture.floor = c.boolean("floor", true);
    s.capture.vtu = c.boolean("vtu", false);
    s.capture.cutObj = c.boolean("cut_obj", false);
    if (c.has("floor_height")) s.capture.floorHeight = c.number("floor_height", 0, -1e6, 1e6);
    if (c.has("check")) {
        ObjectReader k = c.object("check");
        CheckSettings& ch = s.capture.check;
        ch.maxDiff = k.integer("max_diff", ch.maxDiff, 0, 255);
        ch.maxFailing = k.number("max_failing", ch.maxFailing, 0, 1);
        if (k.has("frames")) {
            const json& f = k.raw("frames");
            if (!f.is_array() || f.empty()) k.fail("frames", "must be a non-empty array of frame numbers or \"last\"");
            for (const json& e : f) {
                if (e.is_string() && e.get<std::string>() == "last")
                    ch.frames.push_back(-1);
                else if (e.is_number_integer() && e.get<long>() >= 0 && e.get<long>() < 100000000)
                    ch.frames.push_back(e.get<int>());
                else
                    k.fail("frames", "entries must be frame numbers >= 0 or \"last\", got " + e.dump());
            }
            k.touch("frames");
        }
        k.finish();
    }
    c.finish();
}

}  // namespace

SceneDef parseScene(const json& j, const std::string& file) {
    SceneDef s;
    s.file = file;
    s.dir = fs::path(file).parent_path().string();
    s.source = j;
    ObjectReader root(j, file, "");
    s.name = root.string("name", fs::path(file).stem().string());
    root.touch("description");

    readObjectSection(root, s);
    if (root.has("material")) {
        ObjectReader m = root.object("material");
        // documented ranges: beyond them the stiffness rows over- or underflow in the Lanczos solve
        s.material.E = m.number("E", s.material.E, 1e-3, 1e13);
        s.material.nu = m.number("nu", s.material.nu, -1, 0.5, true, true);
        s.material.rho = m.number("rho", s.material.rho, 1e-3, 1e6);
        s.damping = m.number("damping", 0, 0, 1e300);
        s.toughness = m.number("toughness", 0, 0, 1e7);
        m.finish();
    }
    for (auto& f : root.array("fixed")) {
        s.fixed.push_back(readRegion(f));
        f.finish();
    }
    if (root.has("loads")) {
        ObjectReader l = root.object("loads");
        s.gravity = l.vec3("gravity", s.gravity);
        for (auto& f : l.array("forces")) {
            ForceLoad fl;
            fl.force = f.requiredVec3("force");
            if (f.has("profile")) {
                ObjectReader pr = f.object("profile");
                fl.profile = readProfile(pr);
            }
            f.touch("force");
            f.touch("profile");
            // the region keys sit beside force and profile
            fl.region = readRegion(f);
            f.finish();
            s.forces.push_back(fl);
        }
        l.finish();
    }
    if (root.has("integrator")) readIntegratorSection(root.object("integrator"), s);
    s.duration = root.number("duration", 1, 0, 1e6, true);
    if (root.has("checks")) {
        ObjectReader c = root.object("checks");
        s.checks.speedFactor = c.number("speed_factor", s.checks.speedFactor, 0, 1e6, true);
        s.checks.displacementFactor = c.number("displacement_factor", s.checks.displacementFactor, 0, 1e6, true);
        s.checks.maxSpeed = c.number("max_speed", 0, 0, 1e300);
        s.checks.maxDisplacement = c.number("max_displacement", 0, 0, 1e300);
        s.checks.energy = c.boolean("energy", true);
        s.checks.invertedFraction = c.number("inverted_fraction", s.checks.invertedFraction, 0, 1);
        s.checks.invertedSteps = c.integer("inverted_steps", s.checks.invertedSteps, 0, 1000000000);
        c.finish();
    }
    if (root.has("cutting")) readCuttingSection(root.object("cutting"), s);
    {
        int i = 0;
        for (auto& t : root.array("tools")) {
            s.tools.push_back(readTool(t, s.dir, i++));
            t.finish();
        }
    }
    {
        int i = 0;
        for (auto& c : root.array("colliders")) {
            s.colliders.push_back(readCollider(c, s.dir, i++));
            c.finish();
        }
    }
    if (root.has("contact")) {
        ObjectReader c = root.object("contact");
        s.contactModel = c.string("model", "projection", {"projection", "penalty"}) == "penalty"
                             ? ContactModel::Penalty
                             : ContactModel::Projection;
        s.pieceContact = c.boolean("pieces", false);
        if (s.pieceContact && s.contactModel == ContactModel::Penalty)
            throw InputError(c.file() + ": " + c.path() +
                             ".pieces: contact between pieces needs contact.model \"projection\" (penalty has none)");
        s.pieceFriction = c.number("piece_friction", s.pieceFriction, 0, 10);
        s.contactSpacing = c.number("spacing", 0, 0, 1e3);
        s.forceRate = c.number("force_rate", 1000, 0, 1e9, true);
        c.finish();
    }
    if (root.has("camera")) {
        ObjectReader c = root.object("camera");
        for (auto& k : c.array("keyframes")) {
            CameraKey ck;
            ck.time = k.number("time", 0, 0);
            ck.eye = k.requiredVec3("eye");
            ck.target = k.requiredVec3("target");
            ck.up = k.vec3("up", ck.up);
            ck.fov = k.number("fov", 40, 1, 170);
            if ((ck.eye - ck.target).norm() < 1e-12) k.fail("eye", "must differ from target");
            k.finish();
            if (!s.camera.empty() && ck.time < s.camera.back().time) k.fail("time", "keyframes must be in time order");
            s.camera.push_back(ck);
        }
        c.finish();
    }
    if (root.has("capture")) readCaptureSection(root.object("capture"), s);
    if (root.has("output")) {
        ObjectReader o = root.object("output");
        s.writeVtu = o.boolean("vtu", true);
        o.finish();
    }
    root.finish();
    return s;
}

SceneDef loadScene(const std::string& path, const std::vector<std::string>& sets) {
    return parseScene(applySets(parseJson(detail::readFile(path), path, true), sets), path);
}

json applySets(json j, const std::vector<std::string>& sets) {
    for (const auto& a : sets) setPath(j, a);
    return j;
}

CutOptions cutOptions(const Cutting& c) {
    CutOptions o;
    o.lumping = c.lumping;
    o.minFraction = c.minFraction;
    o.mergeDebris = c.mergeDebris;
    o.relaxIterations = c.relaxIterations;
    o.lightShare = c.lightShare;
    return o;
}

CutSurface cutSurfaceOf(const CutDef& cd) {
    CutSurface surf;
    surf.point = cd.point;
    surf.normal = cd.normal;
    if (!cd.polygon.empty()) {
        Eigen::Vector3d u, v;
        planeAxes(cd.normal, u, v);
        std::vector<Eigen::Vector2d> poly;
        for (const auto& p : cd.polygon) poly.emplace_back((p - cd.point).dot(u), (p - cd.point).dot(v));
        surf.regions.push_back(std::move(poly));
    }
    return surf;
}

}  // namespace cutsim
