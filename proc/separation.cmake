# The separation core: phase-set accumulator, estimators, quality mask, harmonic gain.
target_sources(ds_proc PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/separation_params.c
  ${CMAKE_CURRENT_LIST_DIR}/separation_accumulate.c
  ${CMAKE_CURRENT_LIST_DIR}/separation_finalize.c
  ${CMAKE_CURRENT_LIST_DIR}/separation_noise.c
  ${CMAKE_CURRENT_LIST_DIR}/separation_kernels.c
  ${CMAKE_CURRENT_LIST_DIR}/harmonic_gain.c
)
# The row loops (separation_kernels.c) are written for the auto-vectoriser, which -O2 alone (GCC 12's
# very-cheap cost model) skips for loops of unknown trip count.
set_source_files_properties(${CMAKE_CURRENT_LIST_DIR}/separation_kernels.c PROPERTIES
  COMPILE_OPTIONS "-ftree-vectorize;$<$<C_COMPILER_ID:GNU>:-fvect-cost-model=dynamic>")
