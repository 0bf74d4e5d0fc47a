// `cutsim dt`: JSON contract, VTU output and errors on bad input.
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>

namespace cutsim {
namespace {

TEST(CmdDt, JsonHoldsTheContractKeysAndTable43Values) {
    std::string out, err;
    const std::string vtu = test::tempDir() + "/liver_dt.vtu";
    const int code = test::runCutsim(
        "dt " + test::data("tet/sofa_liver.msh") + " --scale 0.0254 --json --worst 3 --vtu " + vtu, &out, &err);
    ASSERT_EQ(code, 0) << err;
    const nlohmann::json j = nlohmann::json::parse(out);
    for (const char* key : {"nodes", "tets", "dt_exact", "dt_certified", "dt_r1r", "dt_hs", "dt_hp", "dt_le",
                            "dt_element", "correlation", "worst", "seconds"})
        EXPECT_TRUE(j.contains(key)) << key;
    EXPECT_EQ(j["nodes"].get<int>(), 181);
    EXPECT_EQ(j["tets"].get<int>(), 596);
    EXPECT_NEAR(j["dt_exact"].get<double>(), 0.4510e-3, 0.005 * 0.4510e-3);
    EXPECT_NEAR(j["dt_r1r"].get<double>(), 0.4514e-3, 0.005 * 0.4514e-3);
    EXPECT_LE(j["dt_certified"].get<double>(), j["dt_exact"].get<double>());
    for (const char* key : {"exact", "certified", "estimators"}) EXPECT_TRUE(j["seconds"].contains(key)) << key;
    for (const char* key : {"volume_length", "harmonic_volume_length", "min_sine_dihedral", "radius_ratio",
                            "mean_ratio", "char_length", "hs", "hp", "le", "element"})
        EXPECT_TRUE(j["correlation"].contains(key)) << key;
    ASSERT_EQ(j["worst"].size(), 3u);
    EXPECT_NEAR(j["worst"][0]["r1r"].get<double>(), j["dt_r1r"].get<double>(), 1e-15);
    for (const char* key : {"element", "r1r", "hs", "hp", "le"}) EXPECT_TRUE(j["worst"][0].contains(key)) << key;
    EXPECT_LE(j["worst"][0]["r1r"].get<double>(), j["worst"][2]["r1r"].get<double>());
    // The VTU holds the per-element fields, including the 0/1 critical flag.
    ASSERT_TRUE(std::filesystem::exists(vtu));
    std::stringstream ss;
    ss << std::ifstream(vtu).rdbuf();
    for (const char* name : {"dt_r1r", "dt_hs", "dt_hp", "dt_le", "dt_element", "critical"})
        EXPECT_NE(ss.str().find(name), std::string::npos) << name;
}

TEST(CmdDt, TableIsReadable) {
    std::string out, err;
    ASSERT_EQ(test::runCutsim("dt " + test::data("tet/sofa_Armadillo_Tetra_4406.vtu") + " --scale 0.01 --worst 4", &out,
                              &err),
              0)
        << err;
    for (const char* s :
         {"nodes:", "tets:", "exact", "certified", "R1R", "Hs", "Hp", "Le", "element", "mean_ratio", "worst"})
        EXPECT_NE(out.find(s), std::string::npos) << s;
}

TEST(CmdDt, BadInputExitsWithCodeTwoAndAMessage) {
    std::string out, err;
    EXPECT_EQ(test::runCutsim("dt " + test::data("tet/no_such_mesh.msh"), &out, &err), 2);
    EXPECT_NE(err.find("error: "), std::string::npos) << err;
    EXPECT_NE(err.find("no_such_mesh.msh"), std::string::npos) << err;
    EXPECT_EQ(test::runCutsim("dt " + test::data("broken/sofa_6_tetra_bad.msh"), &out, &err), 2);
    EXPECT_NE(err.find("error: "), std::string::npos) << err;
    EXPECT_NE(err.find("sofa_6_tetra_bad.msh"), std::string::npos) << err;
    EXPECT_EQ(test::runCutsim("dt " + test::data("tet/sofa_liver.msh") + " --nu 0.5", &out, &err), 2);
    EXPECT_NE(err.find("error: material"), std::string::npos) << err;
}

}  // namespace
}  // namespace cutsim
