# The GPIO illuminator and trigger backends through the simulated chip.
if(TARGET ds_drivers_gpio)
  add_executable(test_gpio ${CMAKE_CURRENT_LIST_DIR}/test_gpio.c)
  target_link_libraries(test_gpio ds_drivers_gpio)
  add_test(NAME drivers/gpio COMMAND test_gpio)
  set_tests_properties(drivers/gpio PROPERTIES LABELS drivers TIMEOUT 60)
endif()
