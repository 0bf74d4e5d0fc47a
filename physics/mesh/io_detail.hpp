// Internals shared by the mesh readers: a bounded token cursor that knows its line, and the
// checks every tet reader ends with. Not part of the public interface.
#pragma once

#include "mesh/io.hpp"

#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace cutsim::detail {

// Whole file as bytes; InputError if it is missing or unreadable.
std::string readFile(const std::string& path);

// InputError naming `path` unless every coordinate is within kMaxCoordinate and the points span at
// least kMinExtent.
// Throws the coordinate-range error `why` of path, naming scaleKey when the scale is not 1.
[[noreturn]] void failScaled(const std::string& path, const std::string& scaleKey, double scale,
                             const std::string& why);
void checkCoordinateRange(const std::string& path, const Eigen::Matrix3Xd& X, const std::string& scaleKey = {},
                          double scale = 1);

// Lower-case copy, for case-insensitive keywords and extensions.
std::string lower(std::string_view s);

// Whitespace-separated tokens over text owned by the caller. Every read is bounds-checked and
// every failure is an InputError "file:line: reason".
class Tokens {
public:
    Tokens(std::string path, std::string_view text, char comment = '\0', long firstLine = 1);

    bool atEnd();                                  // no token left
    std::string_view peek();                       // next token without consuming it ("" at end)
    long peekLine();                               // line of the next token (last line at end)
    std::string_view next(std::string_view what);  // consume; EOF is an error naming `what`
    long lastLine() const { return lastLine_; }    // line of the token last consumed

    // Numbers; with `line` > 0 the token must be on that line (a short line is an error).
    long integer(std::string_view what, long line = 0);
    double real(std::string_view what, long line = 0);  // finite only
    // Entry count from a header, bounded by what the rest of the file could hold (each entry at
    // least `bytesPerEntry` bytes), so a corrupt count cannot drive a huge allocation.
    long count(std::string_view what, long bytesPerEntry = 2);

    void skipRestOfLine();  // drop what is left of the current line
    void skipLine();        // skip the whole line of the next token

    [[noreturn]] void fail(const std::string& why, long line = -1) const;
    const std::string& path() const { return path_; }

private:
    void skipSpace();
    std::string path_;
    std::string_view text_;
    char comment_;
    size_t pos_ = 0;
    long line_;      // line at pos_
    long lastLine_;  // line of the last consumed token
};

// Unbounded counts must not drive allocations: reserve at most this many entries up front.
inline size_t boundedReserve(long n) { return static_cast<size_t>(n < 0 ? 0 : (n > (1 << 20) ? (1 << 20) : n)); }

// File node ids -> 0-based indices.
class IdMap {
public:
    bool add(long id, int index) { return map_.emplace(id, index).second; }  // false: duplicate
    int find(long id) const {
        auto it = map_.find(id);
        return it == map_.end() ? -1 : it->second;
    }
    void reserve(size_t n) { map_.reserve(n); }

private:
    std::unordered_map<long, int> map_;
};

// A tet mesh as read, before scaling and checks.
struct RawTets {
    std::vector<double> xyz;    // 3 per node
    std::vector<long> nodeIds;  // file id per node; empty when ids are implicit
    std::vector<int> tets;      // 4 node indices per tet, 0-based, already range-checked
    std::vector<long> tetLine;  // line of each tet in `tetFile`
    std::vector<long> tetId;    // file element id of each tet; empty when implicit
    std::string tetFile;        // file holding the elements (TetGen: the .ele)
    int skipped = 0;            // non-tet elements
};

// Scale, volume checks (zero volume, inversion) and the report; shared by every tet reader.
TetMesh finishTetMesh(const std::string& path, RawTets&& raw, const ReadOptions& opts, ReadReport* report);

// Format readers (raw, before checks).
RawTets readMsh(const std::string& path, const std::string& text);
RawTets readTetGen(const std::string& nodePath, const std::string& elePath);
RawTets readMedit(const std::string& path, const std::string& text);
RawTets readVtu(const std::string& path, const std::string& text);

SurfaceMesh readObj(const std::string& path, const std::string& text);
SurfaceMesh readOff(const std::string& path, const std::string& text);
SurfaceMesh readStl(const std::string& path, const std::string& text);

}  // namespace cutsim::detail
