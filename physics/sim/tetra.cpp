#include "sim/tetra.hpp"

#include "cut/remesh.hpp"
#include "embed/winding.hpp"
#include "improve/improve.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "embed/surface_distance.hpp"
#include "util/memory.hpp"
#include "util/stopwatch.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <cstring>
#include <vector>

namespace cutsim {

namespace fs = std::filesystem;

namespace {

constexpr double kMaxTets = 2e7;           // TetGen's estimated output, at most (as object.box.cells)
constexpr double kBytesPerTet = 1000;      // meshing and improving, per element (as a run's)
constexpr double kBoundaryShare = 0.009;   // the improver's boundary bound, of the diagonal: under the 1% promised
constexpr int kCacheVersion = 5;           // bump when the pipeline's result changes
constexpr double kBoundOverMedian = 2;     // TetGen's volume bound over the median tet it makes
constexpr double kMesherShare = 0.0075;    // Gmsh's share of the volume and boundary bounds (Auto: TetGen beyond)
constexpr double kImproverShare = 0.004;   // the improver's boundary bound after Gmsh, at least (first pass)
constexpr double kFinalShare = 0.0095;     // Gmsh's result from the surface (both ways), at most, of the diagonal
constexpr double kKeptCreases = 60;        // the improver's second pass keeps edges turning more [deg]
constexpr double kImproveWork = 110;       // the improver's budget, 12x12 problems per element (at cutsim
                                           // improve's 140 igl_bunny took 3.3 s per 10k tets, over the 3 s aimed at)
constexpr double kVolumeShare = 0.009;     // the volume bound the pipeline keeps: under the 1% promised
constexpr double kDistanceSpacing = 2e-4;  // the distances' sampling, of the diagonal (their error at most
                                           // a 1/sqrt(3) of it)

std::string fmt(const char* f, auto... args) {
    char buf[512];
    std::snprintf(buf, sizeof buf, f, args...);
    return buf;
}

// Edge of the regular tet of volume v: v = a^3 / (6 sqrt 2).
double regularEdge(double v) { return std::cbrt(6 * std::sqrt(2.0) * v); }

// The surface with only the vertices its triangles use.
SurfaceMesh compacted(const SurfaceMesh& s) {
    std::vector<int> to(static_cast<size_t>(s.vertices()), -1);
    SurfaceMesh out;
    out.source = s.source;
    out.F.resize(3, s.faces());
    int n = 0;
    for (int f = 0; f < s.faces(); ++f)
        for (int k = 0; k < 3; ++k) {
            int& t = to[static_cast<size_t>(s.F(k, f))];
            if (t < 0) t = n++;
            out.F(k, f) = t;
        }
    out.V.resize(3, n);
    for (int v = 0; v < s.vertices(); ++v)
        if (to[static_cast<size_t>(v)] >= 0) out.V.col(to[static_cast<size_t>(v)]) = s.V.col(v);
    return out;
}

std::uint64_t fnv1a(std::uint64_t h, const void* data, size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ULL;
    return h;
}

fs::path cacheFolder() {
    if (const char* c = std::getenv("CUTSIM_CACHE"); c && *c) return c;
    if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) return fs::path(x) / "cutsim";
    if (const char* h = std::getenv("HOME"); h && *h) return fs::path(h) / ".cache" / "cutsim";
    return fs::temp_directory_path() / "cutsim-cache";
}

std::string readText(const fs::path& p) {
    std::ifstream in(p);
    std::string t((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    while (!t.empty() && std::isspace(static_cast<unsigned char>(t.back()))) t.pop_back();
    return t;
}

struct GmshOutcome {
    TetMesh mesh;
    double angle = 0;     // crease angle Gmsh used [deg]
    int refinements = 0;  // times it was made again with smaller elements where it left `bound`
    std::string error;    // empty: the mesh was made
};

// cutsim-gmsh-tetra on s at the target edge `size`, refined where the surface lies farther than
// `bound` from it [m], through files in a folder of its own.
GmshOutcome runGmsh(const std::string& program, const SurfaceMesh& s, double size, double bound) {
    static std::atomic<int> runs{0};
    const fs::path dir = fs::temp_directory_path() / fmt("cutsim-gmsh-%010ld-%06d", long(::getpid()), runs++);
    fs::create_directories(dir);
    GmshOutcome g;
    {
        std::ofstream obj(dir / "in.obj");
        obj.precision(17);
        for (int v = 0; v < s.vertices(); ++v) obj << "v " << s.V(0, v) << ' ' << s.V(1, v) << ' ' << s.V(2, v) << '\n';
        for (int f = 0; f < s.faces(); ++f)
            obj << "f " << s.F(0, f) + 1 << ' ' << s.F(1, f) + 1 << ' ' << s.F(2, f) + 1 << '\n';
        if (!obj) g.error = "cannot write " + (dir / "in.obj").string();
    }
    const std::string in = (dir / "in.obj").string(), out = (dir / "out.msh").string(),
                      log = (dir / "out.txt").string(), err = (dir / "err.txt").string(), h = fmt("%.17g", size),
                      b = fmt("%.17g", bound);
    if (g.error.empty()) {
        posix_spawn_file_actions_t fa;
        posix_spawn_file_actions_init(&fa);
        posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        posix_spawn_file_actions_addopen(&fa, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        std::vector<char*> argv;
        for (const std::string* a : {&program, &in, &out, &h, &b}) argv.push_back(const_cast<char*>(a->c_str()));
        argv.push_back(nullptr);
        // A fixed environment: Gmsh's mesh depends on the OpenMP thread count, and on the
        // environment the program starts with (its heap's layout orders some of its sets), neither
        // of which may depend on the caller.
        char oneThread[] = "OMP_NUM_THREADS=1", locale[] = "LC_ALL=C";
        std::vector<char*> env{oneThread, locale, nullptr};
        pid_t pid = 0;
        const int rc = posix_spawn(&pid, program.c_str(), &fa, nullptr, argv.data(), env.data());
        posix_spawn_file_actions_destroy(&fa);
        int status = 0;
        if (rc != 0)
            g.error = "cannot start " + program + ": " + std::strerror(rc);
        else if (::waitpid(pid, &status, 0) < 0)
            g.error = "lost " + program;
        else if (WIFSIGNALED(status))
            g.error = fmt("cutsim-gmsh-tetra was killed by signal %d", WTERMSIG(status));
        else if (WEXITSTATUS(status) != 0) {
            g.error = readText(err);
            if (g.error.starts_with("error: ")) g.error.erase(0, 7);
            if (g.error.empty()) g.error = fmt("cutsim-gmsh-tetra exited with %d", WEXITSTATUS(status));
        }
    }
    if (g.error.empty()) {
        try {
            const nlohmann::json j = nlohmann::json::parse(readText(log));
            g.angle = j.at("angle").get<double>();
            g.refinements = j.at("refinements").get<int>();
            g.mesh = readTetMesh(out);
        } catch (const std::exception& e) {
            g.error = std::string("cutsim-gmsh-tetra's output: ") + e.what();
        }
    }
    std::error_code ec;
    fs::remove_all(dir, ec);
    return g;
}

// The boundary triangles of a tet mesh as a surface (over all its nodes).
SurfaceMesh boundaryOf(const TetMesh& m) {
    SurfaceMesh b;
    b.V = m.X;
    b.F = boundaryFaces(m);
    return b;
}

}  // namespace

const char* mesherName(Mesher m) {
    switch (m) {
    case Mesher::Gmsh: return "gmsh";
    case Mesher::TetGen: return "tetgen";
    case Mesher::Auto: break;
    }
    return "auto";
}

std::string gmshTetraProgram() {
    const char* name = "cutsim-gmsh-tetra";
    std::error_code ec;
    if (const char* e = std::getenv("CUTSIM_GMSH_TETRA"); e && *e) return fs::exists(e, ec) ? e : "";
    std::vector<fs::path> dirs;
    if (const fs::path self = fs::read_symlink("/proc/self/exe", ec); !ec) dirs.push_back(self.parent_path());
#ifdef CUTSIM_PROGRAM_DIRS
    for (const char* d : {CUTSIM_PROGRAM_DIRS}) dirs.emplace_back(d);
#endif
    for (const fs::path& d : dirs)
        if (fs::exists(d / name, ec)) return (d / name).string();
    return "";
}

TetraResult tetraFromSurface(SurfaceMesh surface, const TetraOptions& opts) {
    const std::string src = surface.source;
    if (!(opts.size > 0) || !std::isfinite(opts.size)) throw InputError(src, 0, "the target edge length must be > 0");
    TetraResult res;
    TetraReport& r = res.report;
    Stopwatch sw;

    // 1. A volume needs a closed, consistently oriented, manifold surface (as MI's exact path).
    SurfaceMesh s = compacted(surface);
    if (s.faces() == 0) throw InputError(src, 0, "the surface has no triangle");
    r.diagonal = (s.V.rowwise().maxCoeff() - s.V.rowwise().minCoeff()).norm();
    const SurfaceCleanup clean = cleanSurface(s, 0.0);
    r.degenerateTriangles = clean.degenerateFaces;
    if (clean.duplicateFaces > 0)
        throw InputError(
            src, 0,
            fmt("the surface has %d duplicated triangles (two over the same three vertices)", clean.duplicateFaces));
    s = compacted(s);
    r.surfaceTriangles = s.faces();
    const SurfaceCheck check = checkSurface(s);
    if (check.openEdges > 0)
        throw InputError(src, 0, fmt("the surface is open: %d edges belong to one triangle only", check.openEdges));
    if (check.nonManifoldEdges > 0)
        throw InputError(
            src, 0,
            fmt("the surface is not manifold: %d edges belong to more than two triangles", check.nonManifoldEdges));
    if (check.misorientedEdges > 0)
        throw InputError(src, 0,
                         fmt("the surface is not consistently oriented: %d edges are used twice in the same direction",
                             check.misorientedEdges));
    r.volumeSurface = std::abs(enclosedVolume(s));
    // TetGen's tets lie under its volume bound, most near half of it: a bound of twice the regular
    // tet of edge `size` makes the median element about that tet
    const double tetVolume = kBoundOverMedian * opts.size * opts.size * opts.size / (6 * std::sqrt(2.0));
    const double estimate = kBoundOverMedian * r.volumeSurface / tetVolume;
    if (estimate > kMaxTets && opts.sizeKey.empty())
        throw InputError(src, 0,
                         fmt("--size %g m makes about %.3g tets of this %.3g m^3 volume (at most %.0e): is the scale "
                             "right?",
                             opts.size, estimate, r.volumeSurface, kMaxTets));
    if (estimate > kMaxTets)  // the key's error, the surface named beside it
        throw InputError(opts.sizeKey + ": " +
                         fmt("%g m makes about %.3g tets of the %.3g m^3 volume of %s (at most %.0e): is the scale "
                             "right?",
                             opts.size, estimate, r.volumeSurface, src.c_str(), kMaxTets));
    checkMemory(opts.sizeKey.empty() ? src : opts.sizeKey + " (surface " + src + ")", estimate * kBytesPerTet);
    r.seconds.emplace_back("check", sw.seconds());

    // 2. Gmsh (Geuzaine and Remacle 2009): the surface remeshed at the target edge (finer where it
    // would leave its share of the boundary bound), filled by HXT; kept when its volume and
    // boundary stay within that share (Auto; else TetGen).
    TetMesh mesh;
    if (opts.mesher != Mesher::TetGen) {
        sw = Stopwatch();
        const std::string program = gmshTetraProgram();
        if (program.empty() && opts.mesher == Mesher::Gmsh)
            throw std::runtime_error("the Gmsh mesher, cutsim-gmsh-tetra, is not installed (libgmsh-dev)");
        if (program.empty()) r.mesherNote = "cutsim-gmsh-tetra not installed";
        GmshOutcome g;
        if (!program.empty()) g = runGmsh(program, s, opts.size, kMesherShare * r.diagonal);
        if (!program.empty() && !g.error.empty()) {
            if (opts.mesher == Mesher::Gmsh)
                throw std::runtime_error(src + ": Gmsh could not mesh the surface: " + g.error);
            r.mesherNote = "Gmsh failed: " + g.error;
        }
        r.seconds.emplace_back("gmsh", sw.seconds());
        if (!program.empty() && g.error.empty()) {
            sw = Stopwatch();
            r.meshedVolume = totalVolume(g.mesh);
            r.meshedDistance = hausdorffDistance(s, boundaryOf(g.mesh), kDistanceSpacing * r.diagonal);
            r.seconds.emplace_back("measure_gmsh", sw.seconds());
            const double dv = r.meshedVolume / r.volumeSurface - 1;
            if (opts.mesher == Mesher::Gmsh ||
                (std::abs(dv) <= kMesherShare && r.meshedDistance <= kMesherShare * r.diagonal)) {
                mesh = std::move(g.mesh);
                r.mesher = "gmsh";
                r.creaseAngle = g.angle;
                r.gmshRefinements = g.refinements;
            } else {
                r.mesherNote = fmt("Gmsh's mesh left the bounds (volume %+.2f %%, boundary %.2f %% of the diagonal)",
                                   100 * dv, 100 * r.meshedDistance / r.diagonal);
            }
        }
    }

    // 3. TetGen (Si 2015): the surface kept (p), radius-edge ratio at most 1.4 (q), the volume bound
    // above (a); 0-based, quiet.
    if (r.mesher.empty()) {
        sw = Stopwatch();
        try {
            mesh = tetgenSurface(s, fmt("pq1.4a%.17gzQ", tetVolume));
        } catch (const RemeshError& e) {
            throw InputError(src, 0,
                             std::string("TetGen could not fill the surface (a self-intersecting surface is the "
                                         "usual cause): ") +
                                 e.what());
        }
        r.mesher = "tetgen";
        r.seconds.emplace_back("tetgen", sw.seconds());
    }
    mesh.source = src;
    r.tetsMeshed = mesh.elements();

    // 4. The improver (thesis sec. 5.1) within 0.9% of the diagonal of the surface, both ways, on
    // its work budget (no wall limit: the result, and so the cache, must not depend on the
    // machine's load). Gmsh's share of the bounds is taken off the improver's, but Gmsh's distance
    // lies at a few tips and rims, seldom where the improver moves the boundary: the first pass may
    // use at least kImproverShare and the measured result decides. Should it lie over kFinalShare
    // from the surface, the improver runs again from Gmsh's mesh within the bound less Gmsh's
    // share, with creases and corners kept (kKeptCreases).
    ImproveOptions io;
    io.material = opts.material;
    io.threads = opts.threads;
    io.maxEvaluations = static_cast<long long>(kImproveWork * mesh.elements());
    const double strict = std::max(0.0, kBoundaryShare - r.meshedDistance / r.diagonal);
    io.maxBoundaryDistance = r.mesher == "gmsh" ? std::max(strict, kImproverShare) : strict;
    io.boundaryBothWays = true;
    if (r.mesher == "gmsh")
        io.maxVolumeChange = std::max(0.0, kVolumeShare - std::abs(r.meshedVolume / r.volumeSurface - 1));
    const TetMesh meshed = r.mesher == "gmsh" && opts.improve ? mesh : TetMesh{};
    for (int pass = 0; pass < 2; ++pass) {
        sw = Stopwatch();
        if (opts.improve) {
            const ImproveReport ir = improveMesh(mesh, io);
            r.dtBefore = ir.before.dtExact;
            r.dtAfter = ir.after.dtExact;
            r.boundaryDistance = ir.boundaryDistance;  // from the mesher's boundary: TetGen's is the surface
        } else {
            r.dtBefore = r.dtAfter = meshStepStats(mesh, opts.material).dtExact;
        }
        r.seconds.emplace_back(pass == 0 ? "improve" : "improve_creases", sw.seconds());

        // 5. Spatial order: threads taking ranges of elements then share few nodes.
        sw = Stopwatch();
        mesh = spatialOrder(mesh);
        r.seconds.emplace_back("order", sw.seconds());
        if (r.mesher != "gmsh") break;

        // Gmsh's boundary is not the surface: the result's, measured against it both ways.
        sw = Stopwatch();
        r.boundaryDistance = hausdorffDistance(s, boundaryOf(mesh), kDistanceSpacing * r.diagonal);
        r.seconds.emplace_back("measure", sw.seconds());
        if (!opts.improve || pass == 1 || r.boundaryDistance <= kFinalShare * r.diagonal) break;
        mesh = meshed;
        io.maxBoundaryDistance = strict;
        io.featureAngleDeg = kKeptCreases;
        r.improverCreases = kKeptCreases;
    }

    std::vector<double> vol(static_cast<size_t>(mesh.elements()));
    for (int e = 0; e < mesh.elements(); ++e) vol[static_cast<size_t>(e)] = tetSignedVolume(mesh, e);
    r.volumeMesh = totalVolume(mesh);
    r.minVolume = *std::min_element(vol.begin(), vol.end());
    r.inverted = static_cast<int>(std::count_if(vol.begin(), vol.end(), [](double v) { return !(v > 0); }));
    std::nth_element(vol.begin(), vol.begin() + static_cast<long>(vol.size() / 2), vol.end());
    r.regularEdge = regularEdge(vol[vol.size() / 2]);
    r.dtScale = r.regularEdge / opts.material.pWaveSpeed();
    r.nodes = mesh.nodes();
    r.tets = mesh.elements();
    res.mesh = std::move(mesh);
    return res;
}

TetMesh tetraCached(const std::string& path, double scale, const TetraOptions& opts, bool& cached, TetraReport& report,
                    std::string& cacheFile, const std::string& scaleKey) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path, 0, "cannot open the surface file");
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::uint64_t h = fnv1a(1469598103934665603ULL, bytes.data(), bytes.size());
    // the mesher that will run (Auto: Gmsh when its program is there)
    const Mesher mesher = opts.mesher != Mesher::Auto  ? opts.mesher
                          : gmshTetraProgram().empty() ? Mesher::TetGen
                                                       : Mesher::Gmsh;
    const double key[] = {scale,
                          double(int(mesher)),
                          opts.size,
                          opts.material.E,
                          opts.material.nu,
                          opts.material.rho,
                          double(opts.improve),
                          double(opts.threads),
                          double(kCacheVersion)};
    h = fnv1a(h, key, sizeof key);
    const std::string ext = fs::path(path).extension().string();  // the reader follows the extension
    h = fnv1a(h, ext.data(), ext.size());
    const fs::path folder = cacheFolder();
    const fs::path file = folder / fmt("tetra-%016llx.msh", static_cast<unsigned long long>(h));
    cacheFile = file.string();
    std::error_code ec;
    if (fs::exists(file, ec)) {
        try {
            TetMesh m = readTetMesh(file.string());
            m.source = path;
            cached = true;
            return m;
        } catch (const InputError&) {
            // a damaged cache file is built again below
        }
    }
    cached = false;
    TetraResult r = tetraFromSurface(readSurfaceMesh(path, scale, scaleKey), opts);
    report = r.report;
    // Written whole or not at all, under a name of this process, then renamed into place: a
    // reader never sees half a mesh, and two runs building the same mesh do not collide.
    fs::create_directories(folder, ec);
    const fs::path tmp = folder / fmt("tetra-%016llx.%ld.msh", static_cast<unsigned long long>(h), long(::getpid()));
    try {
        writeMsh22(tmp.string(), r.mesh);
        fs::rename(tmp, file, ec);
        if (ec) fs::remove(tmp, ec);
    } catch (const InputError& e) {
        report.cacheError = e.what();
        cacheFile.clear();
    }
    if (ec) {
        if (report.cacheError.empty()) report.cacheError = ec.message();
        cacheFile.clear();
    }
    r.mesh.source = path;
    return std::move(r.mesh);
}

}  // namespace cutsim
