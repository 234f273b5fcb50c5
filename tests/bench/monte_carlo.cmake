# Monte Carlo transport speed on one core (docs/benchmarks.md). ctest runs --quick.
if(TARGET ds_sim_transport)
  add_executable(bench_monte_carlo ${CMAKE_CURRENT_LIST_DIR}/monte_carlo.c)
  target_link_libraries(bench_monte_carlo PRIVATE ds_sim_transport)
  add_test(NAME bench/monte_carlo COMMAND bench_monte_carlo --quick)
  set_tests_properties(bench/monte_carlo PROPERTIES LABELS bench)
endif()
