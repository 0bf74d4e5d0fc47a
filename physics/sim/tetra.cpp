#include "sim/tetra.hpp"

#include "cut/remesh.hpp"
#include "embed/winding.hpp"
#include "improve/improve.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "util/memory.hpp"
#include "util/stopwatch.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>

namespace cutsim {

namespace fs = std::filesystem;

namespace {

constexpr double kMaxTets = 2e7;          // TetGen's estimated output, at most (as object.box.cells)
constexpr double kBytesPerTet = 1000;     // meshing and improving, per element (as a run's)
constexpr double kBoundaryShare = 0.009;  // the improver's boundary bound, of the diagonal: under the 1% promised
constexpr int kCacheVersion = 2;          // bump when the pipeline's result changes
constexpr double kBoundOverMedian = 2;    // TetGen's volume bound over the median tet it makes

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

}  // namespace

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

    // 2. TetGen (Si 2015): the surface kept (p), radius-edge ratio at most 1.4 (q), the volume bound
    // above (a); 0-based, quiet.
    sw = Stopwatch();
    TetMesh mesh;
    try {
        mesh = tetgenSurface(s, fmt("pq1.4a%.17gzQ", tetVolume));
    } catch (const RemeshError& e) {
        throw InputError(src, 0,
                         std::string("TetGen could not fill the surface (a self-intersecting surface is the "
                                     "usual cause): ") +
                             e.what());
    }
    mesh.source = src;
    r.tetsMeshed = mesh.elements();
    r.seconds.emplace_back("tetgen", sw.seconds());

    // 3. The improver (thesis sec. 5.1) within 0.9% of the diagonal of the surface, on its work
    // budget (no wall limit: the result, and so the cache, must not depend on the machine's load).
    sw = Stopwatch();
    ImproveOptions io;
    io.material = opts.material;
    io.threads = opts.threads;
    io.maxBoundaryDistance = kBoundaryShare;
    if (opts.improve) {
        const ImproveReport ir = improveMesh(mesh, io);
        r.dtBefore = ir.before.dtExact;
        r.dtAfter = ir.after.dtExact;
        r.boundaryDistance = ir.boundaryDistance;  // from TetGen's boundary, which is the surface
    } else {
        r.dtBefore = r.dtAfter = meshStepStats(mesh, opts.material).dtExact;
    }
    r.seconds.emplace_back("improve", sw.seconds());

    // 4. Spatial order: threads taking ranges of elements then share few nodes.
    sw = Stopwatch();
    mesh = spatialOrder(mesh);
    r.seconds.emplace_back("order", sw.seconds());

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
    const double key[] = {scale,
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
