// Gmsh readers: legacy v1 ($NOD/$ELM), 2.2 ASCII and 4.1 ASCII (entity blocks).
#include "mesh/io_detail.hpp"

#include <climits>
#include <cmath>

namespace cutsim::detail {
namespace {

constexpr int kGmshTet = 4;  // 4-node tetrahedron in every Gmsh version

std::string str(std::string_view s) { return std::string(s); }

// Skip an unknown section up to its end marker ("$Foo" ends at "$EndFoo", "$FOO" at "$ENDFOO").
void skipSection(Tokens& t, std::string_view name) {
    const std::string end = "$end" + lower(name.substr(1));
    const long start = t.lastLine();
    for (;;) {
        if (t.atEnd())
            t.fail("unexpected end of file inside " + str(name) + " (opened at line " + std::to_string(start) + ")");
        if (lower(t.next(end)) == end) return;
    }
}

// The section end marker, which also catches a declared count that is too small.
void expectEnd(Tokens& t, std::string_view endName, long declared, std::string_view what) {
    const long line = t.peekLine();
    const std::string_view tok = t.next(endName);
    if (lower(tok) != lower(endName))
        t.fail("expected " + str(endName) + " after " + std::to_string(declared) + " " + str(what) + ", got '" +
                   str(tok.substr(0, 24)) + "' (declared count too small?)",
               line);
}

// Before each entry: a '$' here means the section ended before its declared count.
void expectEntry(Tokens& t, long i, long n, std::string_view what) {
    const std::string_view tok = t.peek();
    if (!tok.empty() && tok[0] == '$')
        t.fail("only " + std::to_string(i) + " of the declared " + std::to_string(n) + " " + str(what) + " before " +
                   str(tok.substr(0, 24)),
               t.peekLine());
}

void addNode(Tokens& t, RawTets& raw, IdMap& ids, long id, long line) {
    if (raw.nodeIds.size() >= static_cast<size_t>(INT_MAX)) t.fail("too many nodes", line);
    if (!ids.add(id, static_cast<int>(raw.nodeIds.size()))) t.fail("duplicate node id " + std::to_string(id), line);
    raw.nodeIds.push_back(id);
    for (int k = 0; k < 3; ++k) raw.xyz.push_back(t.real("coordinate", line));
}

int nodeIndex(Tokens& t, const IdMap& ids, long line) {
    const long id = t.integer("node id", line);
    const int i = ids.find(id);
    if (i < 0) t.fail("node id " + std::to_string(id) + " does not exist", line);
    return i;
}

void addTet(Tokens& t, RawTets& raw, const IdMap& ids, long elemId, long line) {
    for (int k = 0; k < 4; ++k) raw.tets.push_back(nodeIndex(t, ids, line));
    raw.tetLine.push_back(line);
    raw.tetId.push_back(elemId);
}

// $NOD (v1) and $Nodes (2.2): "id x y z" per line.
void readFlatNodes(Tokens& t, RawTets& raw, IdMap& ids, std::string_view endName) {
    const long n = t.count("node count");
    raw.xyz.reserve(3 * boundedReserve(n));
    raw.nodeIds.reserve(boundedReserve(n));
    ids.reserve(boundedReserve(n));
    for (long i = 0; i < n; ++i) {
        expectEntry(t, i, n, "nodes");
        const long line = t.peekLine();
        addNode(t, raw, ids, t.integer("node id"), line);
    }
    expectEnd(t, endName, n, "nodes");
}

// $ELM (v1: id type reg-phys reg-elem n nodes...) and $Elements (2.2: id type ntags tags... nodes...).
void readFlatElements(Tokens& t, RawTets& raw, const IdMap& ids, bool v1, std::string_view endName) {
    const long n = t.count("element count");
    raw.tets.reserve(4 * boundedReserve(n));
    for (long i = 0; i < n; ++i) {
        expectEntry(t, i, n, "elements");
        const long line = t.peekLine();
        const long id = t.integer("element id");
        const long type = t.integer("element type", line);
        if (type != kGmshTet) {
            t.skipRestOfLine();
            ++raw.skipped;
            continue;
        }
        if (v1) {
            t.integer("physical region", line);
            t.integer("elementary region", line);
            const long nn = t.integer("node count", line);
            if (nn != 4) t.fail("tetrahedron with " + std::to_string(nn) + " nodes", line);
        } else {
            const long ntags = t.integer("tag count", line);
            if (ntags < 0 || ntags > 64) t.fail("implausible tag count " + std::to_string(ntags), line);
            for (long k = 0; k < ntags; ++k) t.integer("tag", line);
        }
        addTet(t, raw, ids, id, line);
    }
    expectEnd(t, endName, n, "elements");
}

// 4.1 $Nodes: entity blocks, each with its tags first and then its coordinates.
void readNodes41(Tokens& t, RawTets& raw, IdMap& ids) {
    const long line0 = t.peekLine();
    const long blocks = t.count("entity block count");
    const long n = t.count("node count");
    t.integer("min node tag", line0);
    t.integer("max node tag", line0);
    raw.xyz.reserve(3 * boundedReserve(n));
    raw.nodeIds.reserve(boundedReserve(n));
    ids.reserve(boundedReserve(n));
    long total = 0;
    std::vector<long> tags;
    for (long b = 0; b < blocks; ++b) {
        expectEntry(t, b, blocks, "node blocks");
        const long line = t.peekLine();
        const long dim = t.integer("entity dimension");
        t.integer("entity tag", line);
        const long parametric = t.integer("parametric flag", line);
        const long nb = t.count("block node count");
        if (dim < 0 || dim > 3) t.fail("entity dimension " + std::to_string(dim) + " not in 0..3", line);
        if (parametric != 0 && parametric != 1) t.fail("parametric flag must be 0 or 1", line);
        tags.clear();
        for (long i = 0; i < nb; ++i) {
            expectEntry(t, i, nb, "node tags of the block");
            tags.push_back(t.integer("node tag"));
        }
        for (long i = 0; i < nb; ++i) {
            expectEntry(t, i, nb, "node coordinates of the block");
            const long cl = t.peekLine();
            addNode(t, raw, ids, tags[static_cast<size_t>(i)], cl);
            if (parametric)  // parametric coordinates follow x y z: one per entity dimension
                for (long k = 0; k < dim; ++k) t.real("parametric coordinate", cl);
        }
        total += nb;
    }
    if (total != n)
        t.fail("blocks hold " + std::to_string(total) + " nodes but the header declares " + std::to_string(n), line0);
    expectEnd(t, "$EndNodes", n, "nodes");
}

// 4.1 $Elements: entity blocks "dim tag type count", then "id nodes..." per line.
void readElements41(Tokens& t, RawTets& raw, const IdMap& ids) {
    const long line0 = t.peekLine();
    const long blocks = t.count("entity block count");
    const long n = t.count("element count");
    t.integer("min element tag", line0);
    t.integer("max element tag", line0);
    raw.tets.reserve(4 * boundedReserve(n));
    long total = 0;
    for (long b = 0; b < blocks; ++b) {
        expectEntry(t, b, blocks, "element blocks");
        const long line = t.peekLine();
        t.integer("entity dimension");
        t.integer("entity tag", line);
        const long type = t.integer("element type", line);
        const long nb = t.count("block element count");
        for (long i = 0; i < nb; ++i) {
            expectEntry(t, i, nb, "elements of the block");
            const long el = t.peekLine();
            const long id = t.integer("element id");
            if (type == kGmshTet) {
                addTet(t, raw, ids, id, el);
            } else {
                t.skipRestOfLine();
                ++raw.skipped;
            }
        }
        total += nb;
    }
    if (total != n)
        t.fail("blocks hold " + std::to_string(total) + " elements but the header declares " + std::to_string(n),
               line0);
    expectEnd(t, "$EndElements", n, "elements");
}

}  // namespace

RawTets readMsh(const std::string& path, const std::string& text) {
    Tokens t(path, text);
    RawTets raw;
    IdMap ids;
    const std::string first = lower(t.peek());
    if (first.empty()) t.fail("empty file");

    if (first == "$nod" || first == "$noe") {
        // Legacy v1: sections only, no format header.
        while (!t.atEnd()) {
            const std::string sec = lower(t.next("section"));
            if (sec == "$nod")
                readFlatNodes(t, raw, ids, "$ENDNOD");
            else if (sec == "$noe")
                readFlatNodes(t, raw, ids, "$ENDNOE");
            else if (sec == "$elm")
                readFlatElements(t, raw, ids, true, "$ENDELM");
            else if (sec.size() > 1 && sec[0] == '$')
                skipSection(t, sec);
            else
                t.fail("expected a section such as $NOD or $ELM, got '" + sec.substr(0, 24) + "'");
        }
        return raw;
    }
    if (first != "$meshformat") t.fail("not a Gmsh file: expected $MeshFormat or $NOD first");

    t.next("$MeshFormat");
    const long line = t.peekLine();
    const double version = t.real("format version");
    const long fileType = t.integer("file type", line);
    t.integer("data size", line);
    if (fileType != 0) t.fail("binary .msh is not supported; save it as ASCII", line);
    const bool v4 = version >= 4.0;
    if (v4 && std::abs(version - 4.1) > 1e-9)
        t.fail("Gmsh format " + std::to_string(version) + " is not supported (2.2 or 4.1 ASCII)", line);
    if (version < 2.0) t.fail("format version " + std::to_string(version) + " in a $MeshFormat header", line);
    expectEnd(t, "$EndMeshFormat", 1, "header line");

    while (!t.atEnd()) {
        const std::string sec = lower(t.next("section"));
        if (sec == "$nodes") {
            if (v4)
                readNodes41(t, raw, ids);
            else
                readFlatNodes(t, raw, ids, "$EndNodes");
        } else if (sec == "$elements") {
            if (v4)
                readElements41(t, raw, ids);
            else
                readFlatElements(t, raw, ids, false, "$EndElements");
        } else if (sec.size() > 1 && sec[0] == '$') {
            skipSection(t, sec);
        } else {
            t.fail("expected a section such as $Nodes or $Elements, got '" + sec.substr(0, 24) + "'");
        }
    }
    return raw;
}

}  // namespace cutsim::detail
