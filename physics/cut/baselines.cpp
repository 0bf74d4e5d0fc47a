#include "cut/baselines.hpp"

#include "cut/remesh.hpp"
#include "improve/region.hpp"
#include "fem/model.hpp"
#include "mesh/generate.hpp"
#include "timestep/timestep.hpp"
#include "util/stopwatch.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

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

NearPlaneOptions NearPlaneOptions::budgeted(double dtCritical) {
    NearPlaneOptions o;
    o.dtCritical = dtCritical;
    o.reach = 0.01;  // the elements the cut made or snapped onto the plane
    o.rankAround = true;
    o.maxProblems = 5000;
    o.maxFreeNodes = 40;
    o.descentSteps = 1;
    o.lean = true;
    o.exactSteps = false;
    return o;
}

NearPlaneReport improveNearPlane(TetMesh& mesh, const CutPlane& plane, const Material& material,
                                 const NearPlaneOptions& o) {
    Stopwatch sw;
    NearPlaneReport rep;
    if (mesh.elements() == 0) return rep;
    double edges = 0;
    for (int e = 0; e < mesh.elements(); ++e)
        for (int a = 0; a < 4; ++a)
            for (int b = a + 1; b < 4; ++b) edges += (mesh.X.col(mesh.tets(a, e)) - mesh.X.col(mesh.tets(b, e))).norm();
    const double band = o.reach * edges / (6.0 * mesh.elements());
    std::vector<int> bandElems;
    for (int e = 0; e < mesh.elements(); ++e) {
        bool isNear = false;
        for (int a = 0; a < 4; ++a)
            isNear |= std::abs(plane.normal.dot(mesh.X.col(mesh.tets(a, e)) - plane.point)) < band;
        if (isNear) bandElems.push_back(e);
    }
    rep.band = static_cast<int>(bandElems.size());
    std::vector<char> isFree(static_cast<size_t>(mesh.nodes()), 0);
    std::vector<int> freeNodes;
    auto freeNodesOf = [&](int e) {
        for (int a = 0; a < 4; ++a) {
            const int i = mesh.tets(a, e);
            if (!isFree[static_cast<size_t>(i)]) freeNodes.push_back(i);
            isFree[static_cast<size_t>(i)] = 1;
        }
    };
    if (o.dtCritical > 0 && !bandElems.empty()) {
        // The band and the elements around its nodes, as a mesh of their own: the band's rows
        // and masses, so its R1R steps, are the whole mesh's. The band comes first in it.
        std::vector<char> inBand(static_cast<size_t>(mesh.elements()), 0), bandNode(isFree.size(), 0);
        for (const int e : bandElems) {
            inBand[static_cast<size_t>(e)] = 1;
            for (int a = 0; a < 4; ++a) bandNode[static_cast<size_t>(mesh.tets(a, e))] = 1;
        }
        std::vector<int> around = bandElems, global, local(bandElems.size());
        for (int e = 0; e < mesh.elements(); ++e) {
            bool touches = false;
            for (int a = 0; a < 4; ++a) touches |= bandNode[static_cast<size_t>(mesh.tets(a, e))] != 0;
            if (o.rankAround && touches && !inBand[static_cast<size_t>(e)]) around.push_back(e);
        }
        const TetMesh sub = subMesh(mesh, around, global);
        const Model m = buildModel(sub, material);
        std::iota(local.begin(), local.end(), 0);
        std::vector<double> lambda(bandElems.size());
        StiffnessRows rows;  // the band's nodes' rows, all its problems need
        rows.nbr.resize(static_cast<size_t>(m.nodes()));
        rows.block.resize(static_cast<size_t>(m.nodes()));
        for (size_t l = 0; l < global.size(); ++l)
            if (bandNode[static_cast<size_t>(global[l])])
                assembleStiffnessRow(m, static_cast<int>(l), rows.nbr[l], rows.block[l]);
        r1rLambdas(m, rows, local.data(), static_cast<int>(local.size()), lambda.data());
        rep.problems = static_cast<long long>(local.size());
        // Critical: 2 / sqrt(lambda) < dtCritical. Worst first: the step is the smallest one's.
        const double above = 4 / (o.dtCritical * o.dtCritical);
        std::vector<int> critical;
        for (const int k : local)
            if (lambda[static_cast<size_t>(k)] > above) critical.push_back(k);
        std::sort(critical.begin(), critical.end(), [&](int a, int b) {
            return lambda[static_cast<size_t>(a)] > lambda[static_cast<size_t>(b)] ||
                   (lambda[static_cast<size_t>(a)] == lambda[static_cast<size_t>(b)] && a < b);
        });
        rep.critical = static_cast<int>(critical.size());
        for (const int k : critical) {
            if (o.maxFreeNodes > 0 && static_cast<int>(freeNodes.size()) >= o.maxFreeNodes) break;
            freeNodesOf(bandElems[static_cast<size_t>(k)]);
        }
    } else {
        for (int e : bandElems) freeNodesOf(e);
    }
    std::sort(freeNodes.begin(), freeNodes.end());
    rep.freeNodes = static_cast<int>(freeNodes.size());
    if (freeNodes.empty()) {
        rep.seconds = sw.seconds();
        return rep;
    }
    long long regionElements = 0;  // elements with a free node: the region improveRegion works on
    for (int e = 0; e < mesh.elements(); ++e) {
        bool in = false;
        for (int a = 0; a < 4; ++a) in |= isFree[static_cast<size_t>(mesh.tets(a, e))] != 0;
        regionElements += in;
    }
    ImproveOptions io;
    io.material = material;
    io.maxRounds = o.rounds;  // a small budget: the improvement has to keep up with cutting
    io.maxEvaluations = std::max(2000LL, o.problemsPerTet * regionElements);
    if (o.maxProblems > 0) io.maxEvaluations = std::min(io.maxEvaluations, std::max(1LL, o.maxProblems - rep.problems));
    io.maxSeconds = o.maxSeconds;
    io.descentSteps = o.descentSteps;
    io.exactSteps = o.exactSteps;
    io.lean = o.lean;
    const ImproveReport r = improveRegion(mesh, freeNodes, io);
    rep.problems += r.evaluations;
    rep.dtBefore = r.before.dtR1R;
    rep.dtAfter = r.after.dtR1R;
    rep.seconds = sw.seconds();
    return rep;
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
        if (method == CutMethod::SubdivisionImproved) improveNearPlane(m, p, material, {.dtCritical = dt0});
        dts.push_back(exactDtOf(m, material));
    }
    return dts;
}

}  // namespace cutsim
