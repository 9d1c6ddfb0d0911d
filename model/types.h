// Common numeric types of clothbench.
#ifndef CLOTHBENCH_MODEL_TYPES_H_
#define CLOTHBENCH_MODEL_TYPES_H_

#include <array>

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace clothbench {

/// N×3 per-particle quantities (positions [m], velocities [m/s], forces [N]).
/// Column-major: the x, y and z columns are contiguous, so the N×N Laplacians
/// act on all three columns in one sparse product (docs/model.md §2.1, `L ⊗ I₃`).
using MatrixN3 = Eigen::Matrix<double, Eigen::Dynamic, 3>;
/// The same N×3 quantities stored row-major: its data is the 3N vector with
/// the interleaved index 3p + c of the tangent system J_α (solver/tangent.h).
using MatrixN3R = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using Vector3 = Eigen::Vector3d;
using Matrix3 = Eigen::Matrix3d;
/// Compressed sparse matrix used for L_K, L_D and A_α (N×N).
using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
using Triplet = Eigen::Triplet<double, int>;
/// A 3×3 block of a 3N×3N matrix: (row particle, column particle).
using BlockPair = std::array<int, 2>;

/// Kernels over particles, springs or matrix columns (forces, A·x) run on the
/// OpenMP threads from this many items up; below it a parallel region costs
/// more than it saves.
constexpr int kParallelMinimum = 20000;

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_TYPES_H_
