# The Modbus illuminator backend against the lab's Modbus TCP controller, in-process on 127.0.0.1.
if(TARGET ds_drivers_modbus AND TARGET ds_labsim_modbus)
  add_executable(test_modbus ${CMAKE_CURRENT_LIST_DIR}/test_modbus.c)
  target_link_libraries(test_modbus ds_drivers_modbus ds_labsim_modbus)
  add_test(NAME drivers/modbus COMMAND test_modbus)
  set_tests_properties(drivers/modbus PROPERTIES LABELS drivers TIMEOUT 60)
endif()
