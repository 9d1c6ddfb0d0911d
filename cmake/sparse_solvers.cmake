# Imported targets for Debian 12's libsuitesparse-dev and libhypre-dev.

# An imported target `target` for the library `lib` and its header `header`
# (found under include/`suffix`), linking the further arguments.
function(clothbench_import_library target header suffix lib)
  find_path(${lib}_INCLUDE_DIR ${header} PATH_SUFFIXES ${suffix} REQUIRED)
  find_library(${lib}_LIBRARY ${lib} REQUIRED)
  add_library(${target} UNKNOWN IMPORTED)
  set_target_properties(${target} PROPERTIES
    IMPORTED_LOCATION "${${lib}_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${${lib}_INCLUDE_DIR}"
    INTERFACE_LINK_LIBRARIES "${ARGN}")
endfunction()

find_library(SUITESPARSECONFIG_LIBRARY suitesparseconfig REQUIRED)
# CHOLMOD (SuiteSparse): the Cholesky preconditioner's factor.
clothbench_import_library(CHOLMOD::CHOLMOD cholmod.h suitesparse cholmod "${SUITESPARSECONFIG_LIBRARY}")
# BoomerAMG (hypre, links MPI).
clothbench_import_library(HYPRE::HYPRE HYPRE.h hypre HYPRE MPI::MPI_C)
# KLU (SuiteSparse), called directly for its symbolic analysis: the fill and
# flop count that predict a cvode/klu or ida/klu run's first factorisation
# (reference/klu_prediction.h). SUNDIALS links it through sunlinsolklu.
clothbench_import_library(KLU::KLU klu.h suitesparse klu "${SUITESPARSECONFIG_LIBRARY}")
