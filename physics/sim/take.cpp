#include "sim/take.hpp"

#include <cmath>
#include <filesystem>
#include <limits>
#include <vector>

namespace cutsim {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json vec(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }

// path (absolute or relative to the scene's folder) as seen from the take's folder
std::string relocate(const std::string& path, const std::string& sceneDir, const fs::path& outDir) {
    fs::path p(path);
    if (p.is_relative()) p = fs::path(sceneDir) / p;
    return fs::absolute(p).lexically_normal().lexically_relative(outDir).string();
}

}  // namespace

void addCameraKey(std::vector<CameraKey>& keys, const CameraKey& previous, const CameraKey& now) {
    auto same = [](const CameraKey& x, const CameraKey& y) {
        return x.eye == y.eye && x.target == y.target && x.up == y.up && x.fov == y.fov;
    };
    if (!keys.empty() && same(keys.back(), now)) return;
    if (!keys.empty() && previous.time > keys.back().time) keys.push_back(previous);  // held until then
    const size_t n = keys.size();
    if (n >= 2 && keys[n - 1].time == now.time && keys[n - 2].time == now.time)
        keys.back() = now;  // moved again at the same time (paused): the latest pose
    else
        keys.push_back(now);
}

void holdToolKeys(ToolDef& t, double now, const Eigen::Vector3d& position,
                  const std::optional<Eigen::Quaterniond>& orientation) {
    const ToolKey at = toolKeyAt(t, now);
    ToolKey held = at;
    held.time = std::nextafter(now, std::numeric_limits<double>::infinity());
    held.pose.position = position;
    if (orientation) held.pose.orientation = orientation->normalized();
    std::erase_if(t.keys, [&](const ToolKey& k) { return k.time >= at.time; });
    t.keys.push_back(at);
    t.keys.push_back(held);
}

json takeScene(const Simulation& sim, const std::string& outFile, const std::vector<CameraKey>* camera) {
    const SceneDef& sc = sim.scene();
    json j = sc.source;
    const fs::path outDir = fs::absolute(fs::path(outFile)).parent_path();
    if (j.contains("object")) {
        json& o = j["object"];
        if (o.contains("mesh") && o["mesh"].is_string())
            o["mesh"] = relocate(o["mesh"].get<std::string>(), sc.dir, outDir);
        if (o.contains("surface") && o["surface"].is_object() && o["surface"].contains("path"))
            o["surface"]["path"] = relocate(o["surface"]["path"].get<std::string>(), sc.dir, outDir);
        if (o.contains("visual") && o["visual"].is_string())
            o["visual"] = relocate(o["visual"].get<std::string>(), sc.dir, outDir);
        if (o.contains("visual") && o["visual"].is_object() && o["visual"].contains("path"))
            o["visual"]["path"] = relocate(o["visual"]["path"].get<std::string>(), sc.dir, outDir);
    }
    const TakeLog& log = sim.takeLog();
    if (j.contains("tools")) {
        std::vector<ToolDef> tools = sc.tools;  // their keys as the holds left them
        for (const TakeLog::Hold& h : log.holds)
            holdToolKeys(tools[static_cast<size_t>(h.tool)], h.time, h.position, h.orientation);
        for (size_t i = 0; i < tools.size() && i < j["tools"].size(); ++i) {
            json& t = j["tools"][i];
            if (t.contains("obj") && t["obj"].is_string())
                t["obj"] = relocate(t["obj"].get<std::string>(), sc.dir, outDir);
            json keys = json::array();
            for (const ToolKey& k : tools[i].keys) {
                json e = {{"time", k.time}, {"position", vec(k.pose.position)}};
                const Eigen::Quaterniond& q = k.pose.orientation;
                if (q.coeffs() != Eigen::Quaterniond::Identity().coeffs())
                    e["quaternion"] = json::array({q.w(), q.x(), q.y(), q.z()});
                if (tools[i].kind == ToolDef::Kind::Grasper) e["opening"] = k.opening;
                keys.push_back(std::move(e));
            }
            t["keyframes"] = std::move(keys);
        }
    }
    const auto& cuts = sc.cutting.cuts;
    if (!cuts.empty() && j.contains("cutting") && j["cutting"].contains("cuts"))
        for (size_t k = 0; k < cuts.size() && k < j["cutting"]["cuts"].size(); ++k)
            j["cutting"]["cuts"][k]["time"] = log.cutTime(sc, k);
    if (camera && !camera->empty()) {
        json keys = json::array();
        for (const CameraKey& c : *camera)
            keys.push_back(
                {{"time", c.time}, {"eye", vec(c.eye)}, {"target", vec(c.target)}, {"up", vec(c.up)}, {"fov", c.fov}});
        j["camera"] = {{"keyframes", std::move(keys)}};
    }
    const double t = sim.state().time;
    if (t > 0 && t < sc.duration && !sim.finished()) j["duration"] = t;
    return j;
}

}  // namespace cutsim
