add_executable(test_stripe_phase ${CMAKE_CURRENT_LIST_DIR}/test_stripe_phase.c)
target_link_libraries(test_stripe_phase PRIVATE ds_proc)
add_test(NAME proc/stripe_phase COMMAND test_stripe_phase)
set_tests_properties(proc/stripe_phase PROPERTIES LABELS proc)
