// TetGen .node/.ele, MEDIT .mesh and VTK XML .vtu (ASCII) tet readers.
#include "mesh/io_detail.hpp"

#include <algorithm>
#include <cctype>
#include <climits>
#include <optional>

namespace cutsim::detail {
namespace {

std::string str(std::string_view s) { return std::string(s); }

// ---- TetGen ----

// A node count, with the rest of the header optional (TetGen fills in defaults).
long optionalOnLine(Tokens& t, long line, std::string_view what, long dflt) {
    return (!t.atEnd() && t.peekLine() == line) ? t.integer(what, line) : dflt;
}

}  // namespace

RawTets readTetGen(const std::string& nodePath, const std::string& elePath) {
    const std::string nodeText = readFile(nodePath);
    const std::string eleText = readFile(elePath);
    RawTets raw;
    raw.tetFile = elePath;
    IdMap ids;

    // .node: "<n> <dim> <#attributes> <#markers>", then "<id> x y z [attributes] [marker]".
    Tokens t(nodePath, nodeText, '#');
    if (t.atEnd()) t.fail("empty file", 1);
    const long hl = t.peekLine();
    const long n = t.count("node count");
    const long dim = optionalOnLine(t, hl, "dimension", 3);
    const long nattr = optionalOnLine(t, hl, "attribute count", 0);
    const long nmark = optionalOnLine(t, hl, "boundary marker flag", 0);
    if (dim != 3) t.fail("dimension " + std::to_string(dim) + ", expected 3", hl);
    if (n == 0) t.fail("no nodes (points kept in a .poly file are not supported)", hl);
    if (nattr < 0 || nattr > 1000) t.fail("implausible attribute count " + std::to_string(nattr), hl);
    if (nmark != 0 && nmark != 1) t.fail("boundary marker flag must be 0 or 1", hl);
    raw.xyz.reserve(3 * boundedReserve(n));
    raw.nodeIds.reserve(boundedReserve(n));
    ids.reserve(boundedReserve(n));
    for (long i = 0; i < n; ++i) {
        const long line = t.peekLine();
        const long id = t.integer("node id");
        if (!ids.add(id, static_cast<int>(raw.nodeIds.size()))) t.fail("duplicate node id " + std::to_string(id), line);
        raw.nodeIds.push_back(id);
        for (int k = 0; k < 3; ++k) raw.xyz.push_back(t.real("coordinate", line));
        for (long k = 0; k < nattr + nmark; ++k) t.real("attribute or marker", line);
    }
    if (!t.atEnd()) t.fail("more entries than the declared " + std::to_string(n) + " nodes", t.peekLine());

    // .ele: "<n> <nodes per tet> <#attributes>", then "<id> n1 n2 n3 n4 [...] [attributes]".
    Tokens e(elePath, eleText, '#');
    if (e.atEnd()) e.fail("empty file", 1);
    const long el = e.peekLine();
    const long nt = e.count("tet count");
    const long per = optionalOnLine(e, el, "nodes per tet", 4);
    const long eattr = optionalOnLine(e, el, "attribute count", 0);
    if (per != 4 && per != 10) e.fail("nodes per tet must be 4 or 10, got " + std::to_string(per), el);
    if (eattr < 0 || eattr > 1000) e.fail("implausible attribute count " + std::to_string(eattr), el);
    raw.tets.reserve(4 * boundedReserve(nt));
    for (long i = 0; i < nt; ++i) {
        const long line = e.peekLine();
        const long id = e.integer("tet id");
        for (long k = 0; k < per; ++k) {
            const long nid = e.integer("node id", line);
            const int idx = ids.find(nid);
            if (idx < 0) e.fail("node id " + std::to_string(nid) + " is not in " + nodePath, line);
            if (k < 4) raw.tets.push_back(idx);  // quadratic tets: the 4 corners come first
        }
        for (long k = 0; k < eattr; ++k) e.real("attribute", line);
        raw.tetLine.push_back(line);
        raw.tetId.push_back(id);
    }
    if (!e.atEnd()) e.fail("more entries than the declared " + std::to_string(nt) + " tets", e.peekLine());
    return raw;
}

RawTets readMedit(const std::string& path, const std::string& text) {
    Tokens t(path, text, '#');
    RawTets raw;
    std::vector<long> tetIdx;  // 1-based vertex numbers, checked once all vertices are known
    long nVerts = 0;
    bool sawVertices = false;
    if (t.atEnd()) t.fail("empty file", 1);
    while (!t.atEnd()) {
        const long kwLine = t.peekLine();
        const std::string kw = lower(t.next("keyword"));
        if (kw == "end") break;
        if (kw == "meshversionformatted") {
            t.integer("format version");
        } else if (kw == "dimension") {
            const long d = t.integer("dimension");
            if (d != 3) t.fail("dimension " + std::to_string(d) + ", expected 3");
        } else if (kw == "vertices") {
            if (sawVertices) t.fail("second Vertices section", kwLine);
            sawVertices = true;
            nVerts = t.count("vertex count");
            if (nVerts > INT_MAX) t.fail("too many vertices");
            raw.xyz.reserve(3 * boundedReserve(nVerts));
            for (long i = 0; i < nVerts; ++i) {
                const long line = t.peekLine();
                for (int k = 0; k < 3; ++k) raw.xyz.push_back(t.real("coordinate", k ? line : 0));
                optionalOnLine(t, line, "reference", 0);
            }
        } else if (kw == "tetrahedra") {
            const long n = t.count("tet count");
            tetIdx.reserve(4 * boundedReserve(n));
            for (long i = 0; i < n; ++i) {
                const long line = t.peekLine();
                for (int k = 0; k < 4; ++k) tetIdx.push_back(t.integer("vertex number", k ? line : 0));
                optionalOnLine(t, line, "reference", 0);
                raw.tetLine.push_back(line);
            }
        } else {
            // Any other section: a count, then one entry per line.
            const std::string_view tok = t.peek();
            if (tok.empty() || !(std::isdigit(static_cast<unsigned char>(tok[0])) || tok[0] == '+'))
                t.fail("unknown keyword '" + kw.substr(0, 24) + "'", kwLine);
            const long n = t.count("entry count of " + kw.substr(0, 24), 2);
            for (long i = 0; i < n; ++i) {
                if (t.atEnd()) t.fail("unexpected end of file inside " + kw.substr(0, 24));
                t.skipLine();
            }
            static const char* kElements[] = {"edges",    "triangles",    "quadrilaterals", "hexahedra", "prisms",
                                              "pyramids", "tetrahedrap2", "trianglesp2",    "edgesp2"};
            if (std::find(std::begin(kElements), std::end(kElements), kw) != std::end(kElements))
                raw.skipped += static_cast<int>(std::min<long>(n, INT_MAX - raw.skipped));
        }
    }
    if (!sawVertices) t.fail("no Vertices section", t.lastLine());
    // Vertex numbers are 1-based and implicit.
    raw.tets.reserve(tetIdx.size());
    for (size_t i = 0; i < tetIdx.size(); ++i) {
        const long v = tetIdx[i];
        if (v < 1 || v > nVerts)
            t.fail("vertex number " + std::to_string(v) + " out of range 1.." + std::to_string(nVerts),
                   raw.tetLine[i / 4]);
        raw.tets.push_back(static_cast<int>(v - 1));
    }
    return raw;
}

namespace {

// ---- VTU: a small tag scanner, enough for ASCII UnstructuredGrid files ----

struct Tag {
    size_t begin = std::string::npos;  // position of '<'
    size_t end = std::string::npos;    // one past '>'
    std::string_view text;             // "<Name attr=... >"
    bool selfClosing = false;
    bool found() const { return begin != std::string::npos; }
};

// Next opening tag <name ...> at or after `from`, before `limit`.
Tag findTag(std::string_view text, std::string_view name, size_t from, size_t limit = std::string::npos) {
    Tag tag;
    limit = std::min(limit, text.size());
    for (size_t p = text.find(std::string("<") + str(name), from); p != std::string::npos && p < limit;
         p = text.find(std::string("<") + str(name), p + 1)) {
        const size_t after = p + 1 + name.size();
        if (after >= text.size()) break;
        const char c = text[after];
        if (c != ' ' && c != '\t' && c != '\r' && c != '\n' && c != '>' && c != '/') continue;
        const size_t close = text.find('>', after);
        if (close == std::string::npos) break;
        tag.begin = p;
        tag.end = close + 1;
        tag.text = text.substr(p, tag.end - p);
        tag.selfClosing = text[close - 1] == '/';
        return tag;
    }
    return tag;
}

// Attribute value of key="value" (or 'value') inside a tag.
std::optional<std::string> attribute(std::string_view tag, std::string_view key) {
    for (size_t p = tag.find(key); p != std::string::npos; p = tag.find(key, p + 1)) {
        if (p == 0 || !(tag[p - 1] == ' ' || tag[p - 1] == '\t' || tag[p - 1] == '\n' || tag[p - 1] == '\r')) continue;
        size_t q = p + key.size();
        while (q < tag.size() && (tag[q] == ' ' || tag[q] == '\t')) ++q;
        if (q >= tag.size() || tag[q] != '=') continue;
        ++q;
        while (q < tag.size() && (tag[q] == ' ' || tag[q] == '\t')) ++q;
        if (q >= tag.size() || (tag[q] != '"' && tag[q] != '\'')) continue;
        const size_t close = tag.find(tag[q], q + 1);
        if (close == std::string::npos) return std::nullopt;
        return str(tag.substr(q + 1, close - q - 1));
    }
    return std::nullopt;
}

class VtuReader {
public:
    VtuReader(const std::string& path, std::string_view text) : path_(path), text_(text) {}

    long lineAt(size_t pos) const {
        return 1 + static_cast<long>(std::count(text_.begin(), text_.begin() + std::min(pos, text_.size()), '\n'));
    }
    [[noreturn]] void fail(size_t pos, const std::string& why) const { throw InputError(path_, lineAt(pos), why); }

    long attrCount(const Tag& tag, std::string_view key) const {
        const auto v = attribute(tag.text, key);
        if (!v) fail(tag.begin, "missing attribute " + str(key));
        Tokens t(path_, *v, '\0', lineAt(tag.begin));
        const long n = t.integer(key);
        if (n < 0 || n > INT_MAX) fail(tag.begin, str(key) + " out of range");
        if (!t.atEnd()) fail(tag.begin, "bad value of " + str(key));
        return n;
    }

    // Content of an ASCII DataArray, with a cursor that reports lines of the whole file.
    Tokens content(const Tag& tag, std::string_view what) const {
        const auto fmt = attribute(tag.text, "format");
        if (fmt && *fmt != "ascii")
            fail(tag.begin, str(what) + " has format=\"" + *fmt + "\"; only ASCII VTU is supported");
        if (tag.selfClosing) return Tokens(path_, std::string_view(), '\0', lineAt(tag.begin));
        const size_t close = text_.find("</DataArray>", tag.end);
        if (close == std::string::npos) fail(tag.begin, str(what) + " DataArray is not closed (file truncated?)");
        return Tokens(path_, text_.substr(tag.end, close - tag.end), '\0', lineAt(tag.end));
    }

    RawTets read() {
        RawTets raw;
        const Tag file = findTag(text_, "VTKFile", 0);
        if (!file.found()) fail(0, "not a VTK XML file (no <VTKFile> tag)");
        if (text_.find("</VTKFile>", file.end) == std::string::npos)
            fail(text_.find_last_not_of(" \t\r\n"), "no closing </VTKFile> (file truncated?)");
        if (attribute(file.text, "type").value_or("") != "UnstructuredGrid")
            fail(file.begin, "VTK file type is not UnstructuredGrid");
        if (findTag(text_, "AppendedData", file.end).found())
            fail(findTag(text_, "AppendedData", file.end).begin, "appended (binary) data is not supported");
        const Tag piece = findTag(text_, "Piece", file.end);
        if (!piece.found()) fail(file.begin, "no <Piece> (file truncated?)");
        if (findTag(text_, "Piece", piece.end).found())
            fail(findTag(text_, "Piece", piece.end).begin, "more than one <Piece> is not supported");
        const long nP = attrCount(piece, "NumberOfPoints");
        const long nC = attrCount(piece, "NumberOfCells");

        // Points: the one DataArray inside <Points>.
        const Tag points = findTag(text_, "Points", piece.end);
        if (!points.found()) fail(piece.begin, "no <Points> (file truncated?)");
        const size_t pointsEnd = text_.find("</Points>", points.end);
        const Tag pa = findTag(text_, "DataArray", points.end, pointsEnd);
        if (!pa.found()) fail(points.begin, "no DataArray inside <Points>");
        if (attribute(pa.text, "NumberOfComponents").value_or("1") != "3")
            fail(pa.begin, "Points need NumberOfComponents=\"3\"");
        {
            Tokens t = content(pa, "Points");
            raw.xyz.reserve(3 * boundedReserve(nP));
            for (long i = 0; i < 3 * nP; ++i) raw.xyz.push_back(t.real("point coordinate"));
            if (!t.atEnd()) t.fail("more coordinates than NumberOfPoints=" + std::to_string(nP), t.peekLine());
        }

        // Cells: connectivity, offsets and types, by name.
        const Tag cells = findTag(text_, "Cells", piece.end);
        if (!cells.found()) fail(piece.begin, "no <Cells> (file truncated?)");
        const size_t cellsEnd = text_.find("</Cells>", cells.end);
        std::vector<long> conn, connLine, offsets, types;
        long offsetsLine = 0;
        bool haveConn = false, haveOffsets = false, haveTypes = false;
        for (Tag a = findTag(text_, "DataArray", cells.end, cellsEnd); a.found();
             a = findTag(text_, "DataArray", a.end, cellsEnd)) {
            const std::string name = attribute(a.text, "Name").value_or("");
            if (name == "connectivity") {
                haveConn = true;
                Tokens t = content(a, name);
                while (!t.atEnd()) {
                    conn.push_back(t.integer("node index"));
                    connLine.push_back(t.lastLine());
                }
            } else if (name == "offsets" || name == "types") {
                Tokens t = content(a, name);
                std::vector<long>& dst = name == "offsets" ? offsets : types;
                if (name == "offsets") offsetsLine = lineAt(a.end);
                (name == "offsets" ? haveOffsets : haveTypes) = true;
                dst.reserve(boundedReserve(nC));
                for (long i = 0; i < nC; ++i) dst.push_back(t.integer(name == "offsets" ? "cell offset" : "cell type"));
                if (!t.atEnd()) t.fail("more " + name + " than NumberOfCells=" + std::to_string(nC), t.peekLine());
            }
        }
        if (!haveConn || !haveOffsets || !haveTypes)
            fail(cells.begin, "<Cells> needs connectivity, offsets and types DataArrays");

        raw.tets.reserve(4 * boundedReserve(nC));
        long begin = 0;
        for (long c = 0; c < nC; ++c) {
            const long end = offsets[static_cast<size_t>(c)];
            if (end < begin || end > static_cast<long>(conn.size()))
                throw InputError(path_, offsetsLine,
                                 "cell " + std::to_string(c) + " offset " + std::to_string(end) +
                                     " is out of order or past the connectivity");
            const long cl =
                begin < static_cast<long>(connLine.size()) ? connLine[static_cast<size_t>(begin)] : offsetsLine;
            if (types[static_cast<size_t>(c)] == 10) {  // VTK_TETRA
                if (end - begin != 4)
                    throw InputError(path_, cl,
                                     "tetrahedron cell " + std::to_string(c) + " has " + std::to_string(end - begin) +
                                         " nodes");
                for (long k = begin; k < end; ++k) {
                    const long v = conn[static_cast<size_t>(k)];
                    if (v < 0 || v >= nP)
                        throw InputError(path_, connLine[static_cast<size_t>(k)],
                                         "node index " + std::to_string(v) + " out of range 0.." +
                                             std::to_string(nP - 1));
                    raw.tets.push_back(static_cast<int>(v));
                }
                raw.tetLine.push_back(cl);
            } else {
                ++raw.skipped;
            }
            begin = end;
        }
        if (begin != static_cast<long>(conn.size()))
            throw InputError(path_, offsetsLine,
                             "connectivity has " + std::to_string(conn.size()) + " entries but the last offset is " +
                                 std::to_string(begin));
        return raw;
    }

private:
    const std::string& path_;
    std::string_view text_;
};

}  // namespace

RawTets readVtu(const std::string& path, const std::string& text) { return VtuReader(path, text).read(); }

}  // namespace cutsim::detail
