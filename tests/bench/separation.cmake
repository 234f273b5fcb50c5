# Separation speed against numpy, OpenCV and memcpy (docs/benchmarks.md). ctest runs --quick.
if(EXISTS ${CMAKE_SOURCE_DIR}/proc/separation.cmake)
  add_executable(bench_separation ${CMAKE_CURRENT_LIST_DIR}/separation.c)
  target_link_libraries(bench_separation PRIVATE ds_proc)
  target_compile_definitions(bench_separation PRIVATE
    DS_BENCH_PYTHON="${DESCATTER_PYTHON}"
    DS_BENCH_NUMPY_SCRIPT="${CMAKE_CURRENT_LIST_DIR}/separation_numpy.py")
  add_test(NAME bench/separation COMMAND bench_separation --quick)
  set_tests_properties(bench/separation PROPERTIES LABELS bench)
endif()
