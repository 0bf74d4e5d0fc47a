// libFuzzer target: the surface readers (OBJ, OFF, binary and ASCII STL) and the surface clean-up
// and edge check that mesh intersection starts with.
#include "embed/winding.hpp"
#include "fuzz_support.hpp"
#include "mesh/io_detail.hpp"

using namespace cutsim;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    for (auto read : {detail::readObj, detail::readOff, detail::readStl}) {
        fuzz::expectInputError([&] {
            SurfaceMesh s = read("f.surface", text);
            detail::checkCoordinateRange("f.surface", s.V);
            if (s.faces() == 0) return;
            cleanSurface(s, 0);
            (void)checkSurface(s);
        });
    }
    return 0;
}
