# The blocking protocol client (descatterctl, tests) and descatterctl itself.
add_library(ds_client STATIC ${CMAKE_CURRENT_LIST_DIR}/client.c)
target_link_libraries(ds_client PUBLIC ds_protocol PkgConfig::GLIB PkgConfig::JSONGLIB)
if(TARGET ds_ctl_separate)
  add_executable(descatterctl
    ${CMAKE_CURRENT_LIST_DIR}/descatterctl.c
    ${CMAKE_CURRENT_LIST_DIR}/ctl_remote.c
    ${CMAKE_CURRENT_LIST_DIR}/ctl_output.c)
  target_link_libraries(descatterctl PRIVATE ds_client ds_ctl_separate ds_proc)
  install(TARGETS descatterctl RUNTIME DESTINATION bin)
endif()
