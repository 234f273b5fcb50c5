# `descatterctl separate`: offline separation of a phase folder. A small library so that tests
# can call ds_ctl_separate () directly. Needs the separation core (proc/separation*.c).
if(EXISTS ${CMAKE_SOURCE_DIR}/proc/separation.cmake)
  add_library(ds_ctl_separate STATIC ${CMAKE_CURRENT_LIST_DIR}/ctl_separate.c)
  target_link_libraries(ds_ctl_separate PUBLIC ds_proc PkgConfig::JSONGLIB PkgConfig::GLIB)
endif()
