#include "cut/baselines.hpp"

#include "cut/remesh.hpp"
#include "improve/region.hpp"
#include "fem/model.hpp"
#include "mesh/generate.hpp"
#include "timestep/timestep.hpp"
#include "util/stopwatch.hpp"

#include <cmath>

namespace cutsim {

const char* cutMethodName(CutMethod m) {
    switch (m) {
    case CutMethod::Subdivision: return "subdivision";
    case CutMethod::Remesh: return "remesh";
    case CutMethod::SubdivisionImproved: return "subdivision_improve";
    }
    return "?";
}

CutMethod parseCutMethod(const std::string& name) {
    for (const CutMethod m : {CutMethod::Subdivision, CutMethod::Remesh, CutMethod::SubdivisionImproved})
        if (name == cutMethodName(m)) return m;
    throw InputError("unknown cut method \"" + name + "\" (subdivision, remesh, subdivision_improve)");
}

double improveNearPlane(TetMesh& mesh, const CutPlane& plane, const Material& material, double dtCritical, double reach,
                        int rounds, double maxSeconds) {
    Stopwatch sw;
    if (mesh.elements() == 0) return 0;
    double edges = 0;
    for (int e = 0; e < mesh.elements(); ++e)
        for (int a = 0; a < 4; ++a)
            for (int b = a + 1; b < 4; ++b) edges += (mesh.X.col(mesh.tets(a, e)) - mesh.X.col(mesh.tets(b, e))).norm();
    const double band = reach * edges / (6.0 * mesh.elements());
    std::vector<int> bandElems;
    for (int e = 0; e < mesh.elements(); ++e) {
        bool isNear = false;
        for (int a = 0; a < 4; ++a)
            isNear |= std::abs(plane.normal.dot(mesh.X.col(mesh.tets(a, e)) - plane.point)) < band;
        if (isNear) bandElems.push_back(e);
    }
    std::vector<char> isFree(static_cast<size_t>(mesh.nodes()), 0);
    if (dtCritical > 0 && !bandElems.empty()) {
        // The band as a mesh of its own: the R1R steps of its inner elements are the whole mesh's.
        std::vector<int> global;
        const TetMesh sub = subMesh(mesh, bandElems, global);
        const Model m = buildModel(sub, material);
        const ElementEstimates est = estimateElements(m);
        for (size_t k = 0; k < bandElems.size(); ++k)
            if (est.r1r(static_cast<Eigen::Index>(k)) < dtCritical)
                for (int a = 0; a < 4; ++a) isFree[static_cast<size_t>(mesh.tets(a, bandElems[k]))] = 1;
    } else {
        for (int e : bandElems)
            for (int a = 0; a < 4; ++a) isFree[static_cast<size_t>(mesh.tets(a, e))] = 1;
    }
    std::vector<int> freeNodes;
    for (int i = 0; i < mesh.nodes(); ++i)
        if (isFree[static_cast<size_t>(i)]) freeNodes.push_back(i);
    if (freeNodes.empty()) return sw.seconds();
    long long regionElements = 0;  // elements with a free node: the region improveRegion works on
    for (int e = 0; e < mesh.elements(); ++e) {
        bool in = false;
        for (int a = 0; a < 4; ++a) in |= isFree[static_cast<size_t>(mesh.tets(a, e))] != 0;
        regionElements += in;
    }
    ImproveOptions io;
    io.material = material;
    io.maxRounds = rounds;  // a small budget: the improvement has to keep up with cutting
    io.maxEvaluations = std::max(2000LL, 100LL * regionElements);
    io.maxSeconds = maxSeconds;
    improveRegion(mesh, freeNodes, io);
    return sw.seconds();
}

TetMesh barMesh(const BarOptions& opts) {
    TetMesh m = boxMesh(opts.unit, opts.unit, 10 * opts.unit, opts.nx, opts.ny, opts.nz);
    m.source = "bar";
    return m;
}

double exactDtOf(const TetMesh& mesh, const Material& material) {
    return exactCriticalDt(buildModel(mesh, material)).dt;
}

std::vector<BaselineRow> barCutBaselines(const BarOptions& opts) {
    const TetMesh bar = barMesh(opts);
    std::vector<BaselineRow> rows;
    for (const double kept : opts.kept) {
        if (!(kept > 0 && kept <= 1))
            throw InputError("bar baselines: kept share " + std::to_string(kept) + " not in (0, 1]");
        for (const CutMethod method : {CutMethod::Subdivision, CutMethod::Remesh}) {
            if (method == CutMethod::Remesh && !opts.remesh) continue;
            TetMesh m;
            if (kept >= 1) {
                m = bar;
            } else {
                const CutPlane plane{Eigen::Vector3d(0, 0, (1 - kept) * 10 * opts.unit), Eigen::Vector3d::UnitZ()};
                if (method == CutMethod::Subdivision) {
                    ConformingOptions co = opts.subdivision;
                    co.keep = KeepSide::Positive;
                    m = conformingCut(bar, plane, co).mesh;
                } else {
                    RemeshOptions ro;
                    ro.keep = KeepSide::Positive;
                    m = remeshCut(bar, plane, ro).mesh;
                }
            }
            rows.push_back({kept, cutMethodName(method), m.nodes(), m.elements(), exactDtOf(m, opts.material)});
        }
    }
    return rows;
}

std::vector<double> dtAfterPlaneCuts(const TetMesh& mesh, const std::vector<CutPlane>& planes, CutMethod method,
                                     const Material& material) {
    std::vector<double> dts;
    TetMesh m = mesh;
    // Remeshing keeps the input's resolution through all cuts.
    RemeshOptions ro;
    if (mesh.elements() > 0) ro.maxVolume = totalVolume(mesh) / mesh.elements();
    // The improvement works on the elements under the uncut step.
    const double dt0 = method == CutMethod::SubdivisionImproved ? exactDtOf(mesh, material) : 0.0;
    for (const CutPlane& p : planes) {
        m = method == CutMethod::Remesh ? remeshCut(m, p, ro).mesh : conformingCut(m, p).mesh;
        if (method == CutMethod::SubdivisionImproved) improveNearPlane(m, p, material, dt0);
        dts.push_back(exactDtOf(m, material));
    }
    return dts;
}

}  // namespace cutsim
