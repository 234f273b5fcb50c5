add_executable(test_pixfmt ${CMAKE_CURRENT_LIST_DIR}/test_pixfmt.c)
target_link_libraries(test_pixfmt PRIVATE ds_proc)
add_test(NAME proc/pixfmt COMMAND test_pixfmt)
set_tests_properties(proc/pixfmt PROPERTIES LABELS proc)
