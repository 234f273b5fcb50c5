# The offline `descatterctl separate` command, driven through its entry point.
if(TARGET ds_ctl_separate)
  add_executable(test_ctl_separate ${CMAKE_CURRENT_LIST_DIR}/test_ctl_separate.c)
  target_link_libraries(test_ctl_separate PRIVATE ds_ctl_separate ds_proc PkgConfig::JSONGLIB)
  add_test(NAME proc/ctl_separate COMMAND test_ctl_separate)
  set_tests_properties(proc/ctl_separate PROPERTIES LABELS proc)
endif()
