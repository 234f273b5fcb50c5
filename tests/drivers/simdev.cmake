# The in-process simulated devices (drivers/simdev) over the scene renderer.
if(TARGET ds_drivers_simdev AND EXISTS ${CMAKE_SOURCE_DIR}/proc/stripe_phase.h)
  add_executable(test_simdev_lab ${CMAKE_CURRENT_LIST_DIR}/simdev_lab.c)
  target_link_libraries(test_simdev_lab ds_drivers_simdev ds_proc)
  target_compile_definitions(test_simdev_lab PRIVATE DS_SCENE_DIR="${CMAKE_SOURCE_DIR}/etc/scenes")
  add_test(NAME drivers/simdev-lab COMMAND test_simdev_lab)
  set_tests_properties(drivers/simdev-lab PROPERTIES LABELS drivers TIMEOUT 120)
endif()
