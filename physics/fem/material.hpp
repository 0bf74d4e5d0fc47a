// Isotropic linear elastic material (docs/method.md sec. 1). SI units.
#pragma once

#include <cmath>

namespace cutsim {

struct Material {
    double E = 30e3;    // Young's modulus [Pa]; thesis default 30 kPa
    double nu = 0.3;    // Poisson's ratio [-], in (-1, 0.5)
    double rho = 1000;  // density [kg/m^3]

    double lambda() const { return E * nu / ((1 + nu) * (1 - 2 * nu)); }   // Lame lambda [Pa]
    double mu() const { return E / (2 * (1 + nu)); }                       // shear modulus [Pa]
    double pWaveModulus() const { return lambda() + 2 * mu(); }            // Ehat [Pa]
    double pWaveSpeed() const { return std::sqrt(pWaveModulus() / rho); }  // c_p [m/s]
    bool valid() const { return E > 0 && nu > -1 && nu < 0.5 && rho > 0; }
};

}  // namespace cutsim
