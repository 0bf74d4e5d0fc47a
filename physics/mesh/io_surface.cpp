// Surface readers: Wavefront .obj, .off and .stl (ASCII or binary). Polygons are fanned.
#include "mesh/io_detail.hpp"

#include <array>
#include <charconv>
#include <cctype>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>

namespace cutsim::detail {
namespace {

SurfaceMesh assemble(const std::vector<double>& xyz, const std::vector<int>& tris) {
    SurfaceMesh s;
    s.V = Eigen::Map<const Eigen::Matrix3Xd>(xyz.data(), 3, static_cast<Eigen::Index>(xyz.size() / 3));
    s.F = Eigen::Map<const Eigen::Matrix3Xi>(tris.data(), 3, static_cast<Eigen::Index>(tris.size() / 3));
    return s;
}

// Fan a polygon (v0, v1, ..., vk) into triangles (v0, vi, vi+1).
void fan(const std::vector<int>& poly, std::vector<int>& tris) {
    for (size_t i = 1; i + 1 < poly.size(); ++i) {
        tris.push_back(poly[0]);
        tris.push_back(poly[i]);
        tris.push_back(poly[i + 1]);
    }
}

// Exact-coordinate welding, as STL repeats every vertex per facet.
class Welder {
public:
    int add(const std::array<double, 3>& p, std::vector<double>& xyz) {
        auto [it, inserted] = map_.try_emplace(p, static_cast<int>(xyz.size() / 3));
        if (inserted) xyz.insert(xyz.end(), p.begin(), p.end());
        return it->second;
    }

private:
    std::map<std::array<double, 3>, int> map_;
};

}  // namespace

SurfaceMesh readObj(const std::string& path, const std::string& text) {
    std::vector<double> xyz;
    std::vector<int> tris;
    std::vector<long> pending, pendingLine;  // positive indices, checked once all vertices are known
    std::vector<int> poly;
    long lineNo = 0;
    for (size_t pos = 0; pos < text.size();) {
        size_t end = text.find('\n', pos);
        if (end == std::string::npos) end = text.size();
        const std::string_view lineText(text.data() + pos, end - pos);
        pos = end + 1;
        ++lineNo;
        Tokens t(path, lineText, '#', lineNo);
        if (t.atEnd()) continue;
        const std::string_view kw = t.next("statement");
        if (kw == "v") {
            for (int k = 0; k < 3; ++k) xyz.push_back(t.real("vertex coordinate", lineNo));
        } else if (kw == "f") {
            // "f a b c", "a/t", "a/t/n" or "a//n"; negative indices count back from the last vertex.
            poly.clear();
            while (!t.atEnd()) {
                const std::string_view tok = t.next("vertex index");
                const std::string_view head = tok.substr(0, tok.find('/'));
                long idx = 0;
                auto [p, ec] = std::from_chars(head.data(), head.data() + head.size(), idx);
                if (ec != std::errc() || p != head.data() + head.size() || head.empty())
                    t.fail("bad face vertex '" + std::string(tok.substr(0, 24)) + "'");
                const long nv = static_cast<long>(xyz.size() / 3);
                if (idx == 0) t.fail("face vertex index 0 (OBJ indices start at 1)");
                if (idx < 0) {
                    if (nv + idx < 0)
                        t.fail("relative vertex index " + std::to_string(idx) + " before the first vertex");
                    poly.push_back(static_cast<int>(nv + idx));
                } else {
                    if (idx > INT_MAX) t.fail("vertex index " + std::to_string(idx) + " out of range");
                    poly.push_back(static_cast<int>(idx - 1));
                    pending.push_back(idx);
                    pendingLine.push_back(lineNo);
                }
            }
            if (poly.size() < 3) t.fail("face with " + std::to_string(poly.size()) + " vertices");
            fan(poly, tris);
        }
        // Other statements (vn, vt, g, o, s, usemtl, mtllib, l, ...) carry nothing we need.
    }
    const long nv = static_cast<long>(xyz.size() / 3);
    for (size_t i = 0; i < pending.size(); ++i)
        if (pending[i] > nv)
            throw InputError(path, pendingLine[i],
                             "vertex index " + std::to_string(pending[i]) + " out of range 1.." + std::to_string(nv));
    return assemble(xyz, tris);
}

SurfaceMesh readOff(const std::string& path, const std::string& text) {
    Tokens t(path, text, '#');
    if (t.atEnd()) t.fail("empty file", 1);
    const std::string_view head = t.next("OFF header");
    if (head.size() < 3 || head.substr(head.size() - 3) != "OFF" || head.find('4') != std::string_view::npos ||
        head[0] == 'n')
        t.fail("not an OFF file (header '" + std::string(head.substr(0, 24)) + "')");
    const long cl = t.peekLine();
    const long nv = t.count("vertex count");
    const long nf = t.count("face count");
    if (!t.atEnd() && t.peekLine() == cl) t.integer("edge count", cl);  // present but unused
    if (nv > INT_MAX) t.fail("too many vertices", cl);

    std::vector<double> xyz;
    xyz.reserve(3 * boundedReserve(nv));
    for (long i = 0; i < nv; ++i) {
        const long line = t.peekLine();
        for (int k = 0; k < 3; ++k) xyz.push_back(t.real("vertex coordinate", k ? line : 0));
        t.skipRestOfLine();  // colours or normals of COFF/NOFF
    }
    std::vector<int> tris, poly;
    tris.reserve(3 * boundedReserve(nf));
    for (long i = 0; i < nf; ++i) {
        const long line = t.peekLine();
        const long n = t.integer("face size");
        if (n < 3 || n > 1000000) t.fail("face with " + std::to_string(n) + " vertices", line);
        poly.clear();
        for (long k = 0; k < n; ++k) {
            const long v = t.integer("vertex index", line);
            if (v < 0 || v >= nv)
                t.fail("vertex index " + std::to_string(v) + " out of range 0.." + std::to_string(nv - 1), line);
            poly.push_back(static_cast<int>(v));
        }
        t.skipRestOfLine();  // face colour
        fan(poly, tris);
    }
    return assemble(xyz, tris);
}

namespace {

SurfaceMesh readStlBinary(const std::string& path, const std::string& bytes, uint32_t n) {
    std::vector<double> xyz;
    std::vector<int> tris;
    tris.reserve(3 * static_cast<size_t>(n));
    Welder weld;
    for (uint32_t f = 0; f < n; ++f) {
        const size_t at = 84 + 50 * static_cast<size_t>(f);
        for (int v = 0; v < 3; ++v) {
            float c[3];
            std::memcpy(c, bytes.data() + at + 12 + 12 * v, sizeof c);  // little-endian float32, after the normal
            std::array<double, 3> p{c[0], c[1], c[2]};
            if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
                throw InputError(path, 0,
                                 "facet " + std::to_string(f) + " (byte " + std::to_string(at) +
                                     "): non-finite vertex coordinate");
            tris.push_back(weld.add(p, xyz));
        }
    }
    return assemble(xyz, tris);
}

SurfaceMesh readStlAscii(const std::string& path, const std::string& text) {
    Tokens t(path, text);
    std::vector<double> xyz;
    std::vector<int> tris, poly;
    Welder weld;
    auto expect = [&](std::string_view word) {
        const std::string_view tok = t.next(word);
        if (lower(tok) != word)
            t.fail("expected '" + std::string(word) + "', got '" + std::string(tok.substr(0, 24)) + "'");
    };
    while (!t.atEnd()) {
        const std::string kw = lower(t.next("facet"));
        if (kw == "solid" || kw == "endsolid") {
            t.skipRestOfLine();  // solid name
        } else if (kw == "facet") {
            const long line = t.lastLine();
            expect("normal");
            for (int k = 0; k < 3; ++k) t.next("normal component");  // recomputed from the vertices if needed
            expect("outer");
            expect("loop");
            poly.clear();
            while (lower(t.peek()) == "vertex") {
                t.next("vertex");
                const long vl = t.lastLine();
                std::array<double, 3> p{};
                for (double& c : p) c = t.real("vertex coordinate", vl);
                poly.push_back(weld.add(p, xyz));
            }
            expect("endloop");
            expect("endfacet");
            if (poly.size() < 3) t.fail("facet with " + std::to_string(poly.size()) + " vertices", line);
            fan(poly, tris);
        } else {
            t.fail("expected 'facet' or 'endsolid', got '" + kw.substr(0, 24) + "'");
        }
    }
    return assemble(xyz, tris);
}

}  // namespace

SurfaceMesh readStl(const std::string& path, const std::string& text) {
    // Binary when the size matches the facet count in the header, whatever the first bytes say
    // (many binary files start with "solid" too).
    if (text.size() >= 84) {
        uint32_t n = 0;
        std::memcpy(&n, text.data() + 80, 4);
        if (text.size() == 84 + 50 * static_cast<uint64_t>(n)) return readStlBinary(path, text, n);
    }
    size_t p = 0;
    while (p < text.size() && std::isspace(static_cast<unsigned char>(text[p]))) ++p;
    if (lower(std::string_view(text).substr(p, 5)) == "solid") return readStlAscii(path, text);
    if (text.size() >= 84) {
        uint32_t n = 0;
        std::memcpy(&n, text.data() + 80, 4);
        throw InputError(path, 0,
                         "binary STL header declares " + std::to_string(n) + " facets (" +
                             std::to_string(84 + 50 * static_cast<uint64_t>(n)) + " bytes) but the file has " +
                             std::to_string(text.size()) + " bytes (truncated?)");
    }
    throw InputError(path, 1, "not an STL file (too short for binary, no 'solid' for ASCII)");
}

}  // namespace cutsim::detail
