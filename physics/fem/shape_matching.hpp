// Shape matching of the hybrid elements (Model::matched; Mueller et al. 2005, as Fierz et al.
// 2012 use it for the elements that would limit an explicit step): after the FEM update, each
// matched element's corners are pulled toward the rigid motion that best fits them.
#pragma once

#include "fem/model.hpp"
#include "fem/state.hpp"

#include <vector>

namespace cutsim {

struct ShapeMatchScratch {
    Eigen::Matrix3Xd pull;     // sum over a node's matched elements of m_ea (g_a - x_a) [kg m]
    std::vector<int> touched;  // nodes with a pull this step
    std::vector<char> mark;    // 1 for the touched nodes (nNodes)
};

// For each matched element e with corner masses m_ea: centre of mass c (c0 at rest), rotation R
// of the polar decomposition of A = sum m_ea (x_a - c)(X_a - c0)^T, goals g_a = c + R (X_a - c0).
// A free node moves by alpha sum_e m_ea (g_a - x_a) / m_i (m_i its whole mass: a node shared with
// FEM elements is pulled by its matched elements' share only) and its velocity by that over dt.
// No energy is added: each pull is a step of at most alpha toward a rigid fit.
void shapeMatch(const Model& m, State& s, double dt, ShapeMatchScratch& w);

}  // namespace cutsim
