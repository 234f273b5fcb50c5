# descatterd: the service (sequencer, devices, service wiring, spool) and its executable.
# Built once every part it wires together exists in the tree.

# The acquisition thread alone (tested against scripted devices in tests/daemon).
if(TARGET ds_drivers_core AND EXISTS ${CMAKE_SOURCE_DIR}/proc/stripe_phase.h
   AND EXISTS ${CMAKE_SOURCE_DIR}/proc/separation.cmake)
  add_library(ds_sequencer STATIC
    ${CMAKE_CURRENT_LIST_DIR}/sequencer.c
    ${CMAKE_CURRENT_LIST_DIR}/phase_check.c
    ${CMAKE_CURRENT_LIST_DIR}/devices_close.c)
  target_link_libraries(ds_sequencer PUBLIC ds_result ds_drivers_core ds_proc ds_operating)
  target_compile_definitions(ds_sequencer PRIVATE G_LOG_DOMAIN="descatterd" G_LOG_USE_STRUCTURED=1)
endif()

if(TARGET ds_sequencer AND TARGET ds_sim AND TARGET ds_drivers_simdev
   AND EXISTS ${DS_DEFAULT_SCENE_FILE})
  # The built-in scene of `descatterd --sim`, embedded so the binary runs from anywhere.
  set(_scene_header ${CMAKE_CURRENT_BINARY_DIR}/daemon/default_scene.h)
  add_custom_command(
    OUTPUT ${_scene_header}
    COMMAND ${CMAKE_COMMAND} -DIN=${DS_DEFAULT_SCENE_FILE} -DOUT=${_scene_header}
            -DNAME=${DS_DEFAULT_SCENE_NAME} -P ${CMAKE_CURRENT_LIST_DIR}/cmake/embed_scene.cmake
    DEPENDS ${DS_DEFAULT_SCENE_FILE} ${CMAKE_CURRENT_LIST_DIR}/cmake/embed_scene.cmake
    COMMENT "Embedding the default scene")
  add_library(ds_daemon_core STATIC
    ${CMAKE_CURRENT_LIST_DIR}/devices.c
    ${CMAKE_CURRENT_LIST_DIR}/spool.c
    ${CMAKE_CURRENT_LIST_DIR}/service.c
    ${_scene_header})
  target_include_directories(ds_daemon_core PRIVATE ${CMAKE_CURRENT_BINARY_DIR})
  # Structured logging: under systemd GLib writes to the journal with these fields.
  target_compile_definitions(ds_daemon_core PRIVATE PROJECT_VERSION="${PROJECT_VERSION}"
                             DS_DEFAULT_OPERATING_MODEL="${CMAKE_SOURCE_DIR}/etc/operating-model.csv"
                             G_LOG_DOMAIN="descatterd" G_LOG_USE_STRUCTURED=1)
  target_link_libraries(ds_daemon_core PUBLIC ds_sequencer ds_result ds_server ds_config ds_proc ds_sim
                        ds_drivers_core ds_drivers_simdev PkgConfig::SYSTEMD)
  # Hardware backends as they exist in the tree (each can be built on its own).
  foreach(backend aravis modbus)
    if(TARGET ds_drivers_${backend})
      string(TOUPPER ${backend} _up)
      target_link_libraries(ds_daemon_core PUBLIC ds_drivers_${backend})
      target_compile_definitions(ds_daemon_core PRIVATE DESCATTER_HAVE_${_up}=1)
    endif()
  endforeach()
  if(TARGET ds_drivers_gpio AND EXISTS ${CMAKE_SOURCE_DIR}/drivers/gpio/gpio_backends.h)
    target_link_libraries(ds_daemon_core PUBLIC ds_drivers_gpio)
    target_compile_definitions(ds_daemon_core PRIVATE DESCATTER_HAVE_GPIO=1)
  endif()
  add_executable(descatterd ${CMAKE_CURRENT_LIST_DIR}/descatterd.c)
  target_compile_definitions(descatterd PRIVATE G_LOG_DOMAIN="descatterd" G_LOG_USE_STRUCTURED=1)
  target_link_libraries(descatterd PRIVATE ds_daemon_core)
  install(TARGETS descatterd RUNTIME DESTINATION bin)
endif()
