// Strict reading of JSON objects: every key known, typed and in range, or an InputError that
// names the key path (e.g. "demo.json: material.nu: must be < 0.5, got 0.5").
#pragma once

#include "mesh/mesh.hpp"

#include <nlohmann/json.hpp>

#include <Eigen/Core>

#include <set>
#include <string>
#include <vector>

namespace cutsim {

class ObjectReader {
public:
    ObjectReader(const nlohmann::json& j, std::string file, std::string path);

    bool has(const std::string& key) const { return j_.contains(key); }
    double number(const std::string& key, double def, double lo = -1e300, double hi = 1e300, bool loOpen = false,
                  bool hiOpen = false);
    double requiredNumber(const std::string& key, double lo = -1e300, double hi = 1e300);
    int integer(const std::string& key, int def, int lo, int hi);
    bool boolean(const std::string& key, bool def);
    std::string string(const std::string& key, const std::string& def, const std::vector<std::string>& allowed = {});
    std::string requiredString(const std::string& key);
    Eigen::Vector3d vec3(const std::string& key, const Eigen::Vector3d& def);
    Eigen::Vector3d requiredVec3(const std::string& key);
    Eigen::Vector3d requiredUnitVec3(const std::string& key);  // normalised; zero refused
    static constexpr double kMaxComponent = 1e9;               // bound on every vector component read
    std::vector<int> intList(const std::string& key);
    ObjectReader object(const std::string& key);              // required object
    std::vector<ObjectReader> array(const std::string& key);  // array of objects, empty if absent
    const nlohmann::json& raw(const std::string& key) const { return j_.at(key); }
    // Marks a key as known without reading it.
    void touch(const std::string& key) { seen_.insert(key); }

    // Throws on any key that was not read.
    void finish() const;

    [[noreturn]] void fail(const std::string& key, const std::string& why) const;
    const std::string& path() const { return path_; }
    const std::string& file() const { return file_; }
    std::string where(const std::string& key) const { return file_ + ": " + keyPath(key); }  // for messages

private:
    const nlohmann::json& get(const std::string& key);
    std::string keyPath(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }

    const nlohmann::json& j_;
    std::string file_, path_;
    std::set<std::string> seen_;
};

}  // namespace cutsim
