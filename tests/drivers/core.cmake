add_executable(test_frame_ids ${CMAKE_CURRENT_LIST_DIR}/test_frame_ids.c)
target_link_libraries(test_frame_ids ds_drivers_core)
add_test(NAME drivers/frame-ids COMMAND test_frame_ids)
set_tests_properties(drivers/frame-ids PROPERTIES LABELS drivers TIMEOUT 60)
