// libFuzzer target: every tet-mesh reader (Gmsh v1 and 2.2, MEDIT, VTU, TetGen) and the checks
// that end them. Bad input must end in InputError; anything else is a finding.
#include "fuzz_support.hpp"
#include "mesh/io_detail.hpp"

using namespace cutsim;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    ReadOptions opts;
    opts.reorient = size % 2 == 1;  // both ways of meeting an inverted tet
    fuzz::expectInputError([&] { detail::finishTetMesh("f.msh", detail::readMsh("f.msh", text), opts, nullptr); });
    fuzz::expectInputError([&] { detail::finishTetMesh("f.mesh", detail::readMedit("f.mesh", text), opts, nullptr); });
    fuzz::expectInputError([&] { detail::finishTetMesh("f.vtu", detail::readVtu("f.vtu", text), opts, nullptr); });
    // TetGen: a .node and an .ele file, split at the first line "#ele"
    const size_t cut = text.find("\n#ele\n");
    const auto files = fuzz::scratchPair("f.node", "f.ele");
    const std::string& node = files.first;  // not a structured binding: clang 14 cannot capture one
    const std::string& ele = files.second;
    fuzz::writeFile(node, text.substr(0, cut));
    fuzz::writeFile(ele, cut == std::string::npos ? std::string() : text.substr(cut + 6));
    fuzz::expectInputError([&] { readTetMesh(node, opts); });
    return 0;
}
