# The blocking protocol client (descatterctl, tests) and descatterctl itself.
add_library(ds_client STATIC ${CMAKE_CURRENT_LIST_DIR}/client.c)
target_link_libraries(ds_client PUBLIC ds_protocol PkgConfig::GLIB PkgConfig::JSONGLIB)
if(TARGET ds_ctl_separate AND TARGET ds_sim)
  add_library(ds_study STATIC ${CMAKE_CURRENT_LIST_DIR}/study.c)
  target_link_libraries(ds_study PUBLIC ds_sim ds_proc ds_operating)
  add_executable(descatterctl
    ${CMAKE_CURRENT_LIST_DIR}/descatterctl.c
    ${CMAKE_CURRENT_LIST_DIR}/ctl_remote.c
    ${CMAKE_CURRENT_LIST_DIR}/ctl_output.c
    ${CMAKE_CURRENT_LIST_DIR}/ctl_study.c)
  target_compile_definitions(descatterctl PRIVATE DS_SCENE_DIR="${CMAKE_SOURCE_DIR}/etc/scenes")
  target_link_libraries(descatterctl PRIVATE ds_client ds_ctl_separate ds_study ds_proc)
  install(TARGETS descatterctl RUNTIME DESTINATION bin)
endif()

# The rig's timing model and the automatic operating point (no simulator needed).
add_library(ds_operating STATIC ${CMAKE_CURRENT_LIST_DIR}/rig_timing.c
            ${CMAKE_CURRENT_LIST_DIR}/operating_point.c)
target_link_libraries(ds_operating PUBLIC ds_proc ds_protocol)
