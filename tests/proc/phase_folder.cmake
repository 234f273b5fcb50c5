add_executable(test_phase_folder ${CMAKE_CURRENT_LIST_DIR}/test_phase_folder.c)
target_link_libraries(test_phase_folder PRIVATE ds_proc)
add_test(NAME proc/phase_folder COMMAND test_phase_folder)
set_tests_properties(proc/phase_folder PROPERTIES LABELS proc)
