// What KLU's symbolic analysis says of a cvode/klu or ida/klu run before
// any factorisation (docs/notes/work-precision.md, "Predicting a first run").
#ifndef CLOTHBENCH_REFERENCE_KLU_PREDICTION_H_
#define CLOTHBENCH_REFERENCE_KLU_PREDICTION_H_

#include <string_view>

#include "model/particle_system.h"
#include "model/types.h"
#include "solver/run.h"

namespace clothbench {

/// KLU's analysis (klu_l_analyze, AMD ordering and BTF as SUNDIALS' KLU
/// solver uses them; Davis & Palamadai Natarajan 2010) of a square sparse
/// matrix: the estimated entries of L and U and flops of one factorisation.
struct KluAnalysis {
  long rows = 0;
  double nnz = 0.0;           ///< entries of the matrix
  double lnz = 0.0, unz = 0.0;  ///< estimated entries of L and U, diagonals included
  double flops = 0.0;         ///< estimated flop count of one factorisation
};

/// @param a n×n, compressed columns (its pattern is what counts)
/// @throws std::runtime_error if KLU refuses the matrix (out of memory)
KluAnalysis AnalyzeKlu(const SparseMatrix& a);

/// What a cvode/klu or ida/klu run on `system` costs at least, before any
/// numerical work: its Newton matrix I − γJ (the pattern of
/// FirstOrderJacobianAtRest, reference/cvode_reference.h) needs at least one
/// factorisation, of KluAnalysis::flops, and holds L and U: 16 bytes per
/// entry (a double and a 64-bit index, klu_l) with the matrix itself. The
/// time is the flops over KLU's flop rate on this machine, measured on the
/// same scene's grid refined to fewer particles (RefineGrid; the leading
/// block of the same matrix where the scene cannot be refined), doubled
/// from 1/256 of the particles until one factorisation takes 0.2 s and 1/64
/// of the full flops (at most a quarter of the particles), and extrapolated
/// to the full flops along the rate's fall between the last two (rate ∝
/// flops^−q, q ≥ 0). A leading block, a strip of the sheet, factorises
/// faster than the square at the same flops (316² sheet: 6.1 GFlop/s at
/// 10¹¹ flops against the refined square's 4.4 at 4.9·10¹⁰), so the
/// refined scene is the calibration. Nothing is predicted
/// (seconds = bytes = 0) where one factorisation is estimated below 10⁹
/// flops, well under a second at the rates measured (docs/notes/work-precision.md,
/// "Predicting a first run").
FirstRunPrediction PredictKluRun(const ParticleSystem& system);

/// The prediction of a CVODE or IDA row of `variant` (MethodEntry::predict):
/// PredictKluRun for "klu", nothing for the reduced solve.
inline FirstRunPrediction PredictKluVariant(const ParticleSystem& system, std::string_view variant) {
  return variant == "klu" ? PredictKluRun(system) : FirstRunPrediction{};
}

}  // namespace clothbench

#endif  // CLOTHBENCH_REFERENCE_KLU_PREDICTION_H_
