// The embedded surface split's private parts (embedded_cut.cpp, past_boundary.cpp): convex
// polygons in a parent's barycentric weights and their clipping, and the cache kept from one
// surface() to the next. Not installed.
#pragma once

#include "cut/vertex_key.hpp"
#include "cut/xfem.hpp"

#include "embed/winding.hpp"

#include <array>
#include <bit>
#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

namespace cutsim {

using Poly = std::vector<Eigen::Vector4d>;  // convex polygon: barycentric weights in one parent, in order

// Part of a convex polygon where an affine function, with values f at its vertices, is >= 0
// (Sutherland-Hodgman; the vertex order, so the orientation, is kept). Empty below 3 vertices.
inline Poly clipPoly(const Poly& p, const std::vector<double>& f) {
    Poly out;
    const size_t n = p.size();
    for (size_t i = 0; i < n; ++i) {
        const size_t j = (i + 1) % n;
        if (f[i] >= 0) out.push_back(p[i]);
        if ((f[i] > 0 && f[j] < 0) || (f[i] < 0 && f[j] > 0)) {
            const double t = f[i] / (f[i] - f[j]);
            out.push_back(p[i] + t * (p[j] - p[i]));
        }
    }
    if (out.size() < 3) out.clear();
    return out;
}

template <class F>
Poly clipBy(const Poly& p, F&& f) {
    std::vector<double> v(p.size());
    for (size_t i = 0; i < p.size(); ++i) v[i] = f(p[i]);
    return clipPoly(p, v);
}

struct CutEngine::SplitCache {
    const EmbeddedSurface* original = nullptr;
    int vertices = 0, faces = 0;
    SurfaceMesh rest;  // the original at rest [m]
    WindingTree tree;  // of rest
    double tinyArea = 0;
    // Each original triangle's parts in the parents it crosses, clipped to their inner faces (CSR by triangle).
    std::vector<int> partStart;
    std::vector<std::pair<int, Poly>> parts;
    std::vector<char> holdsVertex;      // parent holds a surface vertex inside it (nParents)
    bool outside = false;               // a vertex lies outside every element (a visual surface)
    std::vector<char> pastVertex;       // each vertex lies outside its element (nv)
    double reach = 0;                   // farthest a vertex lies outside its element [m]
    std::vector<double> cornerWinding;  // winding number at each original node, NaN until needed
    // Points (N = 4) and segments (N = 8) in a parent, by their weights' bits.
    template <size_t N>
    struct Key {
        int parent;
        std::array<double, N> w;
        bool operator==(const Key&) const = default;
    };
    struct KeyHash {
        template <size_t N>
        size_t operator()(const Key<N>& k) const {
            std::uint64_t h = static_cast<std::uint64_t>(k.parent) * 0x9E3779B97F4A7C15ull;
            for (double x : k.w) h = (h ^ std::bit_cast<std::uint64_t>(x)) * 0x100000001B3ull;
            return static_cast<size_t>(h ^ (h >> 29));
        }
    };
    // Cap samples and rim crossings: a parent's pieces change only when it is cut again.
    std::unordered_map<Key<4>, double, KeyHash> winding;   // winding number at a point
    std::unordered_map<Key<8>, double, KeyHash> crossing;  // where the surface crosses a segment [0, 1]

    // What one original triangle, or one cut parent's cut faces, drew at the last surface(): the
    // vertices in the order they were asked for (not welded across: that is the output's) and
    // triangles on them. Where they go reads only the sides of the elements of the parents sharing
    // a corner with the parents the triangle lies over (with the cut parent), so it is kept until
    // one of those is cut (SurfaceBuild::findChanged); the nodes of the elements the vertices ride
    // only name them (their keys), so a relinked element's are named again.
    struct Drawn {
        std::vector<int> elem;  // the element a vertex rides
        std::vector<Eigen::Vector4d> w;
        std::vector<VertexKey> key;
        std::vector<std::array<int, 4>> tris;  // three vertices and the cut that made it (-1: none)
        // two elements asked whether they are in one piece (a whole-model property), and the answer
        std::vector<std::array<int, 3>> joined;
        // vertices were made one by their keys here (splitPastBoundary's): the elements of those
        // given a vertex already there
        bool welds = false;
        std::vector<int> alsoRide;
        bool whole = false;  // the original triangle as it is (none of the above)
        bool valid = false;
        void clear() {
            elem.clear();
            w.clear();
            key.clear();
            tris.clear();
            joined.clear();
            alsoRide.clear();
            welds = whole = valid = false;
        }
        int add(int e, const Eigen::Vector4d& weights, const VertexKey& k) {
            elem.push_back(e);
            w.push_back(weights);
            key.push_back(k);
            return static_cast<int>(elem.size()) - 1;
        }
    };
    std::vector<Drawn> drawnTri;         // by original triangle
    std::vector<Drawn> drawnCap;         // by parent, for cut parents
    int drawnLevels = -1;                // the capLevels drawnCap was drawn with
    std::vector<int> overStart, over;    // parent -> the original triangles with a vertex or a part in it (CSR)
    std::vector<int> stateStart, state;  // each parent's elements and slivers as the last surface() read them
    Eigen::Matrix4Xi tets;               // the elements' nodes then
    // the output's welding, kept for its buckets
    std::unordered_map<VertexKey, int, VertexKeyHash> welded;
    // splitPastBoundary's marks, by parent and by original node and plane, current at `stamp`
    struct Scratch {
        size_t nodes = 0;
        int stamp = 0;
        std::vector<int> firstMark, lastMark, first, last;
        std::vector<std::vector<int>> nodeStamp;
        std::vector<std::vector<signed char>> nodeSign;
    } scratch;
};

}  // namespace cutsim
