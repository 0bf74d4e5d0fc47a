#include "sim/json_reader.hpp"

#include <cmath>
#include <sstream>

namespace cutsim {

ObjectReader::ObjectReader(const nlohmann::json& j, std::string file, std::string path)
    : j_(j), file_(std::move(file)), path_(std::move(path)) {
    if (!j_.is_object()) throw InputError(file_ + ": " + (path_.empty() ? "scene" : path_) + ": must be an object");
}

void ObjectReader::fail(const std::string& key, const std::string& why) const {
    throw InputError(file_ + ": " + keyPath(key) + ": " + why);
}

const nlohmann::json& ObjectReader::get(const std::string& key) {
    seen_.insert(key);
    return j_.at(key);
}

static std::string num(double v) {
    std::ostringstream s;
    s << v;
    return s.str();
}

double ObjectReader::number(const std::string& key, double def, double lo, double hi, bool loOpen, bool hiOpen) {
    if (!has(key)) return def;
    const auto& v = get(key);
    if (!v.is_number()) fail(key, "must be a number, got " + std::string(v.type_name()));
    const double x = v.get<double>();
    if (!std::isfinite(x)) fail(key, "must be finite");
    if (loOpen ? !(x > lo) : !(x >= lo))
        fail(key, std::string("must be ") + (loOpen ? "> " : ">= ") + num(lo) + ", got " + num(x));
    if (hiOpen ? !(x < hi) : !(x <= hi))
        fail(key, std::string("must be ") + (hiOpen ? "< " : "<= ") + num(hi) + ", got " + num(x));
    return x;
}

double ObjectReader::requiredNumber(const std::string& key, double lo, double hi) {
    if (!has(key)) fail(key, "is required");
    return number(key, 0, lo, hi);
}

int ObjectReader::integer(const std::string& key, int def, int lo, int hi) {
    if (!has(key)) return def;
    const auto& v = get(key);
    if (!v.is_number_integer()) fail(key, "must be an integer, got " + std::string(v.type_name()));
    const std::string range = "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got ";
    // nlohmann keeps integers above 2^63 as unsigned: read as signed they would wrap to -1
    if (v.is_number_unsigned()) {
        const auto u = v.get<unsigned long long>();
        if (u > static_cast<unsigned long long>(hi) || (lo > 0 && u < static_cast<unsigned long long>(lo)))
            fail(key, range + std::to_string(u));
        return static_cast<int>(u);
    }
    const long long x = v.get<long long>();
    if (x < lo || x > hi) fail(key, range + std::to_string(x));
    return static_cast<int>(x);
}

bool ObjectReader::boolean(const std::string& key, bool def) {
    if (!has(key)) return def;
    const auto& v = get(key);
    if (!v.is_boolean()) fail(key, "must be true or false, got " + std::string(v.type_name()));
    return v.get<bool>();
}

std::string ObjectReader::string(const std::string& key, const std::string& def,
                                 const std::vector<std::string>& allowed) {
    if (!has(key)) return def;
    const auto& v = get(key);
    if (!v.is_string()) fail(key, "must be a string, got " + std::string(v.type_name()));
    std::string s = v.get<std::string>();
    if (!allowed.empty()) {
        bool ok = false;
        std::string list;
        for (const auto& a : allowed) {
            ok |= a == s;
            list += (list.empty() ? "" : ", ") + a;
        }
        if (!ok) fail(key, "must be one of " + list + ", got '" + s + "'");
    }
    return s;
}

std::string ObjectReader::requiredString(const std::string& key) {
    if (!has(key)) fail(key, "is required");
    return string(key, "");
}

Eigen::Vector3d ObjectReader::vec3(const std::string& key, const Eigen::Vector3d& def) {
    if (!has(key)) return def;
    const auto& v = get(key);
    if (!v.is_array() || v.size() != 3) fail(key, "must be an array of 3 numbers");
    Eigen::Vector3d r;
    for (int i = 0; i < 3; ++i) {
        if (!v[i].is_number() || !std::isfinite(v[i].get<double>())) fail(key, "must be an array of 3 finite numbers");
        r(i) = v[i].get<double>();
        if (std::abs(r(i)) > kMaxComponent) fail(key, "components must lie within +-1e9");
    }
    return r;
}

Eigen::Vector3d ObjectReader::requiredUnitVec3(const std::string& key) {
    const Eigen::Vector3d v = requiredVec3(key);
    // scaled by the largest component first: the norm of (1e-200, 0, 0) underflows
    const double big = v.cwiseAbs().maxCoeff();
    if (!(big > 1e-300)) fail(key, "must not be zero");
    return (v / big).normalized();
}

Eigen::Vector3d ObjectReader::requiredVec3(const std::string& key) {
    if (!has(key)) fail(key, "is required");
    return vec3(key, Eigen::Vector3d::Zero());
}

std::vector<int> ObjectReader::intList(const std::string& key) {
    std::vector<int> out;
    if (!has(key)) return out;
    const auto& v = get(key);
    if (!v.is_array()) fail(key, "must be an array of integers");
    for (const auto& x : v) {
        if (!x.is_number_integer() || x.get<long long>() < 0 || x.get<long long>() > 2000000000)
            fail(key, "must be an array of non-negative integers");
        out.push_back(static_cast<int>(x.get<long long>()));
    }
    return out;
}

ObjectReader ObjectReader::object(const std::string& key) {
    if (!has(key)) fail(key, "is required");
    const auto& v = get(key);
    if (!v.is_object()) fail(key, "must be an object, got " + std::string(v.type_name()));
    return ObjectReader(v, file_, keyPath(key));
}

std::vector<ObjectReader> ObjectReader::array(const std::string& key) {
    std::vector<ObjectReader> out;
    if (!has(key)) return out;
    const auto& v = get(key);
    if (!v.is_array()) fail(key, "must be an array, got " + std::string(v.type_name()));
    for (size_t i = 0; i < v.size(); ++i) {
        const std::string p = keyPath(key) + "[" + std::to_string(i) + "]";
        if (!v[i].is_object()) throw InputError(file_ + ": " + p + ": must be an object");
        out.emplace_back(v[i], file_, p);
    }
    return out;
}

void ObjectReader::finish() const {
    for (auto it = j_.begin(); it != j_.end(); ++it)
        if (!seen_.count(it.key())) fail(it.key(), "unknown key");
}

}  // namespace cutsim
