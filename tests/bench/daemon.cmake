# descatterd latency and memory (docs/benchmarks.md). Needs the test harness of tests/daemon.
if(TARGET descatterd AND TARGET ds_test_daemon_harness)
  add_executable(bench-daemon ${CMAKE_CURRENT_LIST_DIR}/daemon_latency.c)
  target_link_libraries(bench-daemon ds_test_daemon_harness)
  add_test(NAME bench/daemon COMMAND bench-daemon ${DS_DEFAULT_SCENE_FILE} --quick)
  set_tests_properties(bench/daemon PROPERTIES LABELS bench TIMEOUT 300)
endif()

# Phase-set efficiency on descatter-labsim (real GigE Vision + Modbus on loopback).
if(TARGET descatterd AND TARGET descatter-labsim AND TARGET ds_test_daemon_harness)
  add_executable(bench-labsim ${CMAKE_CURRENT_LIST_DIR}/labsim_efficiency.c)
  target_link_libraries(bench-labsim ds_test_daemon_harness ds_operating ds_sim)
  add_test(NAME bench/labsim COMMAND sh ${CMAKE_SOURCE_DIR}/tests/drivers/netns_run.sh $<TARGET_FILE:bench-labsim>
           $<TARGET_FILE:descatter-labsim> ${DS_DEFAULT_SCENE_FILE} --quick)
  set_tests_properties(bench/labsim PROPERTIES LABELS bench TIMEOUT 300 RESOURCE_LOCK gige_port_3956)
endif()
