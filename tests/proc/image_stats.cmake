add_executable(test_image_stats ${CMAKE_CURRENT_LIST_DIR}/test_image_stats.c)
target_link_libraries(test_image_stats ds_proc)
add_test(NAME proc/image-stats COMMAND test_image_stats)
set_tests_properties(proc/image-stats PROPERTIES LABELS proc TIMEOUT 60)
