# Light transport (Monte Carlo, diffusion, Fresnel, Henyey-Greenstein, RNG, PSF cache) and the
# `slab` subcommand: its own static library so that its tests build without the rest of
# ds_sim; ds_sim links it publicly.
add_library(ds_sim_transport STATIC
  ${CMAKE_CURRENT_LIST_DIR}/rng.c
  ${CMAKE_CURRENT_LIST_DIR}/fresnel.c
  ${CMAKE_CURRENT_LIST_DIR}/henyey_greenstein.c
  ${CMAKE_CURRENT_LIST_DIR}/mc_slab.c
  ${CMAKE_CURRENT_LIST_DIR}/dipole.c
  ${CMAKE_CURRENT_LIST_DIR}/psf_cache.c
  ${CMAKE_CURRENT_LIST_DIR}/sim_slab_cli.c
  ${CMAKE_CURRENT_LIST_DIR}/sim_error.c)
target_link_libraries(ds_sim_transport PUBLIC ds_proc PkgConfig::GLIB ${MATH_LIBRARY})
target_link_libraries(ds_sim PUBLIC ds_sim_transport)
