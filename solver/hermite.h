// Cubic Hermite interpolation inside a step (docs/model.md, "Fixed steps"): the
// run driver's frames and the contact event location use the same
// weights.
#ifndef CLOTHBENCH_SOLVER_HERMITE_H_
#define CLOTHBENCH_SOLVER_HERMITE_H_

namespace clothbench {

/// Weights of the position at s ∈ [0, 1] of a step of size h [s] from
/// (x0, v0) to (x1, v1): x(s) = x0·w.x0 + v0·w.v0 + x1·w.x1 + v1·w.v1, exact
/// at both ends, position error O(h⁴).
struct HermiteWeights {
  double x0, v0, x1, v1;
};
inline HermiteWeights HermitePositionWeights(double s, double h) {
  const double s2 = s * s, s3 = s2 * s;
  return {2 * s3 - 3 * s2 + 1, (s3 - 2 * s2 + s) * h, -2 * s3 + 3 * s2, (s3 - s2) * h};
}

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_HERMITE_H_
