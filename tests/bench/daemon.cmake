# descatterd latency and memory (docs/benchmarks.md). Needs the test harness of tests/daemon.
if(TARGET descatterd AND TARGET ds_test_daemon_harness)
  add_executable(bench-daemon ${CMAKE_CURRENT_LIST_DIR}/daemon_latency.c)
  target_link_libraries(bench-daemon ds_test_daemon_harness)
  add_test(NAME bench/daemon COMMAND bench-daemon ${DS_DEFAULT_SCENE_FILE} --quick)
  set_tests_properties(bench/daemon PROPERTIES LABELS bench TIMEOUT 300)
endif()
