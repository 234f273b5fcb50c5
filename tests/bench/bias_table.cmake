# ds-bias-table: the estimators' noise bias vs N (the table in docs/estimators.md).
# ctest runs the reduced form (--quick); the full table is `build/tests/bench/ds-bias-table`.
file(GLOB _ds_bias_sep ${CMAKE_SOURCE_DIR}/proc/separation*.c)
if(_ds_bias_sep)
  add_executable(ds_bias_table ${CMAKE_CURRENT_LIST_DIR}/bias_table.c)
  set_target_properties(ds_bias_table PROPERTIES OUTPUT_NAME ds-bias-table)
  target_link_libraries(ds_bias_table PRIVATE ds_proc)
  add_test(NAME bench/bias_table COMMAND ds_bias_table --quick)
  set_tests_properties(bench/bias_table PROPERTIES LABELS bench)
endif()
