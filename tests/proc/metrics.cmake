add_executable(test_metrics ${CMAKE_CURRENT_LIST_DIR}/test_metrics.c)
target_link_libraries(test_metrics ds_proc)
add_test(NAME proc/metrics COMMAND test_metrics)
set_tests_properties(proc/metrics PROPERTIES LABELS proc TIMEOUT 60)
