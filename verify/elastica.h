// Continuum reference of chapter-2 experiment 3 (derivation: elastica.md).
#ifndef CLOTHBENCH_VERIFY_ELASTICA_H_
#define CLOTHBENCH_VERIFY_ELASTICA_H_

#include <string>
#include <vector>

namespace clothbench::testing {

struct ElasticaSolution {
  bool ok = false;
  std::string message;
  double kappa0 = 0.0, dkappa0 = 0.0, tension0 = 0.0;  ///< shooting unknowns at s = 0
  double shooting_residual = 0.0;                      ///< max |(κ, z, T)(L)| after Newton
  std::vector<double> x, z;                            ///< positions [m] at the requested s
};

/// Solves B(κ'' − κ³) = Tκ − f cos θ, T' = f sin θ on [0, L] with θ = x = z = 0
/// at s = 0 and κ = z = T = 0 at s = L, by shooting with CVODE.
/// @param length L [m]; @param load f [N/m²]; @param bend B [N m]
/// @param s material coordinates [m] at which to return x(s), z(s)
ElasticaSolution SolveStripElastica(double length, double load, double bend, const std::vector<double>& s);

}  // namespace clothbench::testing

#endif  // CLOTHBENCH_VERIFY_ELASTICA_H_
