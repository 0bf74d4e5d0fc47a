// Reader dispatch, the shared token cursor and checks, and the writers.
#include "mesh/io.hpp"
#include "util/atomic_file.hpp"
#include "mesh/io_detail.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

namespace cutsim {
namespace detail {

std::string readFile(const std::string& path) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec))
        throw InputError(path, 0, ec ? "cannot read: " + ec.message() : std::string("file not found"));
    if (std::filesystem::is_directory(path, ec)) throw InputError(path, 0, "is a folder, not a file");
    // a pipe or a device would block or never end
    if (!std::filesystem::is_regular_file(path, ec)) throw InputError(path, 0, "is not a regular file");
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path, 0, "cannot open file");
    std::ostringstream ss;
    ss << in.rdbuf();
    if (in.bad()) throw InputError(path, 0, "read error");
    return std::move(ss).str();
}

std::string lower(std::string_view s) {
    std::string out(s);
    for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return out;
}

namespace {

// A token as it may appear in a message: short and printable, whatever the file holds.
std::string printable(std::string_view tok) {
    std::string out;
    for (char c : tok.substr(0, 24)) out += (c >= 32 && c < 127) ? c : '?';
    if (tok.size() > 24) out += "...";
    return out;
}

bool isSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v'; }

}  // namespace

Tokens::Tokens(std::string path, std::string_view text, char comment, long firstLine)
    : path_(std::move(path)), text_(text), comment_(comment), line_(firstLine), lastLine_(firstLine) {}

void Tokens::skipSpace() {
    while (pos_ < text_.size()) {
        const char c = text_[pos_];
        if (c == '\n') {
            ++line_;
            ++pos_;
        } else if (isSpace(c)) {
            ++pos_;
        } else if (comment_ != '\0' && c == comment_) {
            while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
        } else {
            break;
        }
    }
}

bool Tokens::atEnd() {
    skipSpace();
    return pos_ >= text_.size();
}

std::string_view Tokens::peek() {
    skipSpace();
    size_t end = pos_;
    while (end < text_.size() && !isSpace(text_[end]) && !(comment_ != '\0' && text_[end] == comment_)) ++end;
    return text_.substr(pos_, end - pos_);
}

long Tokens::peekLine() { return atEnd() ? lastLine_ : line_; }

std::string_view Tokens::next(std::string_view what) {
    const std::string_view tok = peek();
    if (tok.empty()) fail("unexpected end of file, expected " + std::string(what), lastLine_);
    lastLine_ = line_;
    pos_ += tok.size();
    return tok;
}

long Tokens::integer(std::string_view what, long line) {
    if (line > 0 && atEnd()) fail("unexpected end of file, expected " + std::string(what), line);
    if (line > 0 && line_ != line) fail("line ends early, expected " + std::string(what), line);
    std::string_view tok = next(what);
    std::string_view digits = tok;
    if (!digits.empty() && digits[0] == '+') digits.remove_prefix(1);
    long v = 0;
    auto [p, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
    if (ec != std::errc() || p != digits.data() + digits.size() || digits.empty())
        fail("expected " + std::string(what) + ", got '" + printable(tok) + "'");
    return v;
}

double Tokens::real(std::string_view what, long line) {
    if (line > 0 && atEnd()) fail("unexpected end of file, expected " + std::string(what), line);
    if (line > 0 && line_ != line) fail("line ends early, expected " + std::string(what), line);
    std::string_view tok = next(what);
    std::string_view digits = tok;
    if (!digits.empty() && digits[0] == '+') digits.remove_prefix(1);
    double v = 0;
    auto [p, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
    if (ec != std::errc() || p != digits.data() + digits.size() || digits.empty())
        fail("expected " + std::string(what) + ", got '" + printable(tok) + "'");
    if (!std::isfinite(v)) fail("non-finite " + std::string(what) + " '" + printable(tok) + "'");
    return v;
}

long Tokens::count(std::string_view what, long bytesPerEntry) {
    const long n = integer(what);
    if (n < 0) fail("negative " + std::string(what) + " " + std::to_string(n));
    // Each entry needs some bytes: a count beyond that is a corrupt header, not a reason to allocate.
    const long remaining = static_cast<long>(text_.size() - std::min(pos_, text_.size()));
    if (n > remaining / bytesPerEntry + 1)
        fail(std::string(what) + " " + std::to_string(n) + " is more than the rest of the file can hold");
    return n;
}

void Tokens::skipRestOfLine() {
    while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
}

void Tokens::skipLine() {
    skipSpace();
    lastLine_ = line_;
    skipRestOfLine();
}

void Tokens::fail(const std::string& why, long line) const {
    throw InputError(path_, line >= 0 ? line : lastLine_, why);
}

// A coordinate-range error after scaling: the key that gave the scale is blamed when it is not 1.
[[noreturn]] void failScaled(const std::string& path, const std::string& scaleKey, double scale,
                             const std::string& why) {
    if (scaleKey.empty() || scale == 1) throw InputError(path, 0, why);
    std::ostringstream s;
    s << scaleKey << ": " << scale << " applied to " << path << ": " << why;
    throw InputError(s.str());
}

void checkCoordinateRange(const std::string& path, const Eigen::Matrix3Xd& X, const std::string& scaleKey,
                          double scale) {
    if (X.cols() == 0) return;
    Eigen::Index node = 0;
    const double far = X.cwiseAbs().colwise().maxCoeff().maxCoeff(&node);
    if (far > kMaxCoordinate) {
        std::ostringstream why;
        why << "coordinates must lie within +-" << kMaxCoordinate << " m after scaling; node " << node << " is at "
            << far << " m";
        failScaled(path, scaleKey, scale, why.str());
    }
    const double extent = (X.rowwise().maxCoeff() - X.rowwise().minCoeff()).maxCoeff();
    if (X.cols() > 1 && extent < kMinExtent) {
        std::ostringstream why;
        why << "the mesh spans " << extent << " m after scaling; the smallest object simulated is " << kMinExtent
            << " m across";
        failScaled(path, scaleKey, scale, why.str());
    }
}

TetMesh finishTetMesh(const std::string& path, RawTets&& raw, const ReadOptions& opts, ReadReport* report) {
    const std::string& tetFile = raw.tetFile.empty() ? path : raw.tetFile;
    const long nN = static_cast<long>(raw.xyz.size() / 3), nT = static_cast<long>(raw.tets.size() / 4);
    if (nN == 0) throw InputError(path, 0, "no nodes");
    if (nT == 0)
        throw InputError(tetFile, 0,
                         "no tetrahedra" + (raw.skipped > 0
                                                ? " (" + std::to_string(raw.skipped) + " other elements skipped)"
                                                : std::string()));
    if (!(opts.scale > 0) || !std::isfinite(opts.scale))
        throw InputError(path, 0, "scale must be a positive finite number, got " + std::to_string(opts.scale));

    TetMesh m;
    m.X = Eigen::Map<const Eigen::Matrix3Xd>(raw.xyz.data(), 3, nN) * opts.scale;
    if (!m.X.allFinite()) failScaled(path, opts.scaleKey, opts.scale, "coordinates overflow after scaling");
    checkCoordinateRange(path, m.X, opts.scaleKey, opts.scale);
    m.tets = Eigen::Map<const Eigen::Matrix4Xi>(raw.tets.data(), 4, nT);
    m.nodeIds = std::move(raw.nodeIds);
    m.source = path;

    auto name = [&](long e) {
        std::string s = "tet " + std::to_string(e);
        if (static_cast<size_t>(e) < raw.tetId.size()) s += " (element id " + std::to_string(raw.tetId[e]) + ")";
        return s;
    };
    auto lineOf = [&](long e) { return static_cast<size_t>(e) < raw.tetLine.size() ? raw.tetLine[e] : 0L; };

    std::vector<double> vol(static_cast<size_t>(nT));
    double mean = 0;
    for (long e = 0; e < nT; ++e) {
        vol[e] = tetSignedVolume(m, static_cast<int>(e));
        mean += std::abs(vol[e]) / static_cast<double>(nT);
    }
    // Zero volume: relative to the mean so the rule does not depend on units, and relative to the
    // tet's own longest edge cubed, so a mesh flattened as a whole is caught too.
    const double tiny = std::max(1e-14, opts.minVolume) * mean;
    for (long e = 0; e < nT; ++e) {
        double edge2 = 0;
        for (int a = 0; a < 4; ++a)
            for (int b = a + 1; b < 4; ++b)
                edge2 = std::max(edge2, (m.X.col(m.tets(a, e)) - m.X.col(m.tets(b, e))).squaredNorm());
        const double flat = std::abs(vol[e]) / (edge2 * std::sqrt(edge2));
        if (std::abs(vol[e]) <= tiny || !(flat > kMinTetFlatness)) {
            std::ostringstream why;
            if (std::abs(vol[e]) <= tiny)
                why << name(e) << " has zero volume (" << vol[e] << "; the mean tet has " << mean << ")";
            else
                why << name(e) << " is degenerate: its volume " << vol[e] << " is " << flat
                    << " of its longest edge cubed (at least " << kMinTetFlatness << " needed)";
            throw InputError(tetFile, lineOf(e), why.str());
        }
    }

    std::vector<int> inverted;
    for (long e = 0; e < nT; ++e)
        if (vol[e] < 0) inverted.push_back(static_cast<int>(e));
    if (report) report->inverted = inverted;  // filled even when rejected: a caller can list them
    if (!inverted.empty() && !opts.reorient) {
        std::string why = name(inverted[0]) + " is inverted (negative volume); " + std::to_string(inverted.size()) +
                          " inverted in total:";
        for (size_t i = 0; i < inverted.size() && i < 10; ++i) {
            why += ' ';
            why += std::to_string(inverted[i]);
        }
        if (inverted.size() > 10) why += " ...";
        why += "; reorient to fix";
        throw InputError(tetFile, lineOf(inverted[0]), why);
    }
    for (int e : inverted) std::swap(m.tets(2, e), m.tets(3, e));

    std::vector<char> used(static_cast<size_t>(nN), 0);
    for (long i = 0; i < 4 * nT; ++i) used[static_cast<size_t>(m.tets.data()[i])] = 1;
    const int unreferenced = static_cast<int>(std::count(used.begin(), used.end(), 0));

    if (report) {
        report->skippedElements = raw.skipped;
        report->unreferencedNodes = unreferenced;
    }
    return m;
}

}  // namespace detail

namespace {

std::string extensionOf(const std::string& path) {
    return detail::lower(std::filesystem::path(path).extension().string());
}

std::string withExtension(const std::string& path, const std::string& ext) {
    return std::filesystem::path(path).replace_extension(ext).string();
}

// Shortest text that reads back to the same double.
void appendNumber(std::string& out, double v) {
    char buf[32];
    auto [p, ec] = std::to_chars(buf, buf + sizeof buf, v);
    out.append(buf, ec == std::errc() ? p : buf);
}

void appendNumber(std::string& out, long v) {
    char buf[24];
    auto [p, ec] = std::to_chars(buf, buf + sizeof buf, v);
    out.append(buf, ec == std::errc() ? p : buf);
}

void checkWritable(const std::string& path, const TetMesh& mesh) {
    for (long i = 0; i < mesh.tets.size(); ++i)
        if (mesh.tets.data()[i] < 0 || mesh.tets.data()[i] >= mesh.nodes())
            throw InputError(path, 0, "mesh has a node index out of range; nothing written");
    if (!mesh.X.allFinite()) throw InputError(path, 0, "mesh has non-finite coordinates; nothing written");
}

void checkField(const std::string& path, const Field& f, long expected, const char* kind) {
    if (f.name.empty() || f.name.find_first_of("\"<>&") != std::string::npos)
        throw InputError(path, 0, std::string(kind) + " field name '" + f.name + "' is empty or not XML-safe");
    expected *= f.components;
    if (static_cast<long>(f.values.size()) != expected)
        throw InputError(path, 0,
                         std::string(kind) + " field '" + f.name + "' has " + std::to_string(f.values.size()) +
                             " values, expected " + std::to_string(expected));
}

void appendFields(std::string& out, const std::vector<Field>& fields) {
    for (const Field& f : fields) {
        out += "        <DataArray type=\"Float64\" Name=\"" + f.name + "\"";
        if (f.components > 1) out += " NumberOfComponents=\"" + std::to_string(f.components) + "\"";
        out += " format=\"ascii\">\n";
        for (size_t i = 0; i < f.values.size(); ++i) {
            out += (i % 8 == 0) ? "          " : " ";
            appendNumber(out, f.values[i]);
            if (i % 8 == 7 || i + 1 == f.values.size()) out += '\n';
        }
        out += "        </DataArray>\n";
    }
}

}  // namespace

TetMesh readTetMesh(const std::string& path, const ReadOptions& opts, ReadReport* report) {
    const std::string ext = extensionOf(path);
    detail::RawTets raw;
    if (ext == ".msh") {
        raw = detail::readMsh(path, detail::readFile(path));
    } else if (ext == ".node") {
        raw = detail::readTetGen(path, withExtension(path, ".ele"));
    } else if (ext == ".ele") {
        raw = detail::readTetGen(withExtension(path, ".node"), path);
    } else if (ext == ".mesh") {
        raw = detail::readMedit(path, detail::readFile(path));
    } else if (ext == ".vtu") {
        raw = detail::readVtu(path, detail::readFile(path));
    } else if (ext == ".obj" || ext == ".off" || ext == ".stl") {
        throw InputError(path, 0, "is a surface mesh; a tet mesh (.msh, .node/.ele, .mesh, .vtu) is needed here");
    } else {
        throw InputError(path, 0, "unknown mesh extension '" + ext + "' (expected .msh, .node, .ele, .mesh or .vtu)");
    }
    return detail::finishTetMesh(path, std::move(raw), opts, report);
}

SurfaceMesh readSurfaceMesh(const std::string& path, double scale, const std::string& scaleKey) {
    const std::string ext = extensionOf(path);
    if (!(scale > 0) || !std::isfinite(scale))
        throw InputError(path, 0, "scale must be a positive finite number, got " + std::to_string(scale));
    SurfaceMesh s;
    if (ext == ".obj") {
        s = detail::readObj(path, detail::readFile(path));
    } else if (ext == ".off") {
        s = detail::readOff(path, detail::readFile(path));
    } else if (ext == ".stl") {
        s = detail::readStl(path, detail::readFile(path));
    } else {
        throw InputError(path, 0, "unknown surface extension '" + ext + "' (expected .obj, .off or .stl)");
    }
    if (s.vertices() == 0) throw InputError(path, 0, "no vertices");
    if (s.faces() == 0) throw InputError(path, 0, "no faces");
    s.V *= scale;
    if (!s.V.allFinite()) detail::failScaled(path, scaleKey, scale, "coordinates overflow after scaling");
    detail::checkCoordinateRange(path, s.V, scaleKey, scale);
    s.source = path;
    return s;
}

void writeVtu(const std::string& path, const TetMesh& mesh, const std::vector<Field>& cellFields,
              const std::vector<Field>& pointFields) {
    checkWritable(path, mesh);
    for (const Field& f : cellFields) checkField(path, f, mesh.elements(), "cell");
    for (const Field& f : pointFields) checkField(path, f, mesh.nodes(), "point");

    std::string out;
    out.reserve(static_cast<size_t>(64 * mesh.nodes() + 40 * mesh.elements() + 256));
    out += "<?xml version=\"1.0\"?>\n";
    out += "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n";
    out += "  <UnstructuredGrid>\n";
    out += "    <Piece NumberOfPoints=\"" + std::to_string(mesh.nodes()) + "\" NumberOfCells=\"" +
           std::to_string(mesh.elements()) + "\">\n";
    if (!pointFields.empty()) {
        out += "      <PointData>\n";
        appendFields(out, pointFields);
        out += "      </PointData>\n";
    }
    if (!cellFields.empty()) {
        out += "      <CellData>\n";
        appendFields(out, cellFields);
        out += "      </CellData>\n";
    }
    out += "      <Points>\n        <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    for (int i = 0; i < mesh.nodes(); ++i) {
        out += "          ";
        for (int k = 0; k < 3; ++k) {
            if (k) out += ' ';
            appendNumber(out, mesh.X(k, i));
        }
        out += '\n';
    }
    out += "        </DataArray>\n      </Points>\n      <Cells>\n";
    out += "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
    for (int e = 0; e < mesh.elements(); ++e) {
        out += "          ";
        for (int k = 0; k < 4; ++k) {
            if (k) out += ' ';
            appendNumber(out, static_cast<long>(mesh.tets(k, e)));
        }
        out += '\n';
    }
    out += "        </DataArray>\n        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
    for (int e = 0; e < mesh.elements(); ++e) {
        out += (e % 16 == 0) ? "          " : " ";
        appendNumber(out, 4L * (e + 1));
        if (e % 16 == 15 || e + 1 == mesh.elements()) out += '\n';
    }
    out += "        </DataArray>\n        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
    for (int e = 0; e < mesh.elements(); ++e) {
        out += (e % 32 == 0) ? "          10" : " 10";
        if (e % 32 == 31 || e + 1 == mesh.elements()) out += '\n';
    }
    out += "        </DataArray>\n      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n";
    writeFileAtomic(path, out);  // never half a mesh
}

void writeMsh22(const std::string& path, const TetMesh& mesh) {
    checkWritable(path, mesh);
    std::string out;
    out.reserve(static_cast<size_t>(64 * mesh.nodes() + 48 * mesh.elements() + 128));
    out += "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n" + std::to_string(mesh.nodes()) + "\n";
    for (int i = 0; i < mesh.nodes(); ++i) {
        appendNumber(out, static_cast<long>(i) + 1);
        for (int k = 0; k < 3; ++k) {
            out += ' ';
            appendNumber(out, mesh.X(k, i));
        }
        out += '\n';
    }
    out += "$EndNodes\n$Elements\n" + std::to_string(mesh.elements()) + "\n";
    for (int e = 0; e < mesh.elements(); ++e) {
        appendNumber(out, static_cast<long>(e) + 1);
        out += " 4 2 1 1";
        for (int k = 0; k < 4; ++k) {
            out += ' ';
            appendNumber(out, static_cast<long>(mesh.tets(k, e)) + 1);
        }
        out += '\n';
    }
    out += "$EndElements\n";
    writeFileAtomic(path, out);  // never half a mesh
}

}  // namespace cutsim
