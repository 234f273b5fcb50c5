# descatter-labsim over the wire: plain Aravis and the Modbus backend (test_labsim), and programs
# written elsewhere (arv-tool, arv-camera-test, mbpoll: labsim_tools.sh). They bind UDP 3956.
if(TARGET descatter-labsim AND TARGET ds_drivers_modbus)
  add_executable(test_labsim ${CMAKE_CURRENT_LIST_DIR}/test_labsim.c)
  target_link_libraries(test_labsim ds_drivers_modbus ds_sim ds_proc PkgConfig::ARAVIS)
  # netns_run.sh: a private loopback where the machine allows it (see the script).
  add_test(NAME drivers/labsim
           COMMAND sh ${CMAKE_CURRENT_LIST_DIR}/netns_run.sh $<TARGET_FILE:test_labsim>
                   $<TARGET_FILE:descatter-labsim> ${DS_DEFAULT_SCENE_FILE})
  set_tests_properties(drivers/labsim PROPERTIES LABELS drivers TIMEOUT 120 RESOURCE_LOCK gige_port_3956)
  add_test(NAME drivers/labsim-tools
           COMMAND sh ${CMAKE_CURRENT_LIST_DIR}/netns_run.sh sh ${CMAKE_CURRENT_LIST_DIR}/labsim_tools.sh
                   $<TARGET_FILE:descatter-labsim> ${DS_DEFAULT_SCENE_FILE})
  set_tests_properties(drivers/labsim-tools PROPERTIES LABELS drivers TIMEOUT 120 RESOURCE_LOCK gige_port_3956)
endif()
