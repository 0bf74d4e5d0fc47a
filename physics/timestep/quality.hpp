// Standard tetrahedron shape measures of the thesis Table 4.1 and their correlation with the
// time step (thesis sec. 4.1, figs. 4.3 and 4.12).
#pragma once

#include "fem/model.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace cutsim {

// Shape of one tet; each is 1 for the regular tet except minSineDihedral (2 sqrt(2) / 3) and
// charLength (its height). Negative for an inverted tet where the formula carries the volume.
struct TetShape {
    double volumeLength = 0;          // 6 sqrt(2) V / l_rms^3
    double harmonicVolumeLength = 0;  // 6 sqrt(2) V / l_harm^3, harmonic mean of the 6 edges
    double minSineDihedral = 0;       // min over the 6 edges of sin(dihedral angle)
    double radiusRatio = 0;           // 3 r_in / r_circ
    double meanRatio = 0;             // 12 (3V)^(2/3) / sum l^2 (Jacobian based, Liu & Joe)
    double charLength = 0;            // 3 V / largest face area [m]
};
TetShape tetShape(const Eigen::Matrix<double, 3, 4>& X);

// Per-element shape measures of a model (rest positions), one vector per measure.
struct ShapeMeasures {
    Eigen::VectorXd volumeLength, harmonicVolumeLength, minSineDihedral, radiusRatio, meanRatio, charLength;
    void resize(int n);
    void set(int e, const TetShape& s);
};
TetShape elementShape(const Model& m, int e);
ShapeMeasures shapeMeasures(const Model& m);

// Pearson correlation over the entries finite in both vectors; NaN if undefined.
double pearson(const Eigen::VectorXd& a, const Eigen::VectorXd& b);

}  // namespace cutsim
