#include "cut/baselines.hpp"

#include "cut/remesh.hpp"
#include "fem/model.hpp"
#include "mesh/generate.hpp"
#include "timestep/timestep.hpp"

namespace cutsim {

const char* cutMethodName(CutMethod m) { return m == CutMethod::Subdivision ? "subdivision" : "remesh"; }

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
    for (const CutPlane& p : planes) {
        m = method == CutMethod::Subdivision ? conformingCut(m, p).mesh : remeshCut(m, p, ro).mesh;
        dts.push_back(exactDtOf(m, material));
    }
    return dts;
}

}  // namespace cutsim
