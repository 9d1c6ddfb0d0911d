# Imported targets CHOLMOD::CHOLMOD (SuiteSparse) and HYPRE::HYPRE (BoomerAMG,
# links MPI) for Debian 12's libsuitesparse-dev and libhypre-dev.
find_path(CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse REQUIRED)
find_library(CHOLMOD_LIBRARY cholmod REQUIRED)
find_library(SUITESPARSECONFIG_LIBRARY suitesparseconfig REQUIRED)
add_library(CHOLMOD::CHOLMOD UNKNOWN IMPORTED)
set_target_properties(CHOLMOD::CHOLMOD PROPERTIES
  IMPORTED_LOCATION "${CHOLMOD_LIBRARY}"
  INTERFACE_INCLUDE_DIRECTORIES "${CHOLMOD_INCLUDE_DIR}"
  INTERFACE_LINK_LIBRARIES "${SUITESPARSECONFIG_LIBRARY}")

find_path(HYPRE_INCLUDE_DIR HYPRE.h PATH_SUFFIXES hypre REQUIRED)
find_library(HYPRE_LIBRARY HYPRE REQUIRED)
add_library(HYPRE::HYPRE UNKNOWN IMPORTED)
set_target_properties(HYPRE::HYPRE PROPERTIES
  IMPORTED_LOCATION "${HYPRE_LIBRARY}"
  INTERFACE_INCLUDE_DIRECTORIES "${HYPRE_INCLUDE_DIR}"
  INTERFACE_LINK_LIBRARIES MPI::MPI_C)

# KLU (SuiteSparse), called directly for its symbolic analysis: the fill and
# flop count that predict a cvode/klu or ida/klu run's first factorisation
# (reference/klu_prediction.h). SUNDIALS links it through sunlinsolklu.
find_path(KLU_INCLUDE_DIR klu.h PATH_SUFFIXES suitesparse REQUIRED)
find_library(KLU_LIBRARY klu REQUIRED)
add_library(KLU::KLU UNKNOWN IMPORTED)
set_target_properties(KLU::KLU PROPERTIES
  IMPORTED_LOCATION "${KLU_LIBRARY}"
  INTERFACE_INCLUDE_DIRECTORIES "${KLU_INCLUDE_DIR}"
  INTERFACE_LINK_LIBRARIES "${SUITESPARSECONFIG_LIBRARY}")
