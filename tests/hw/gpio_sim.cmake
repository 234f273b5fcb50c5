# The libgpiod backend against the kernel's gpio-sim (configfs); skipped (77) where unavailable.
if(TARGET ds_drivers_gpio)
  add_executable(gpio_sim_drive ${CMAKE_CURRENT_LIST_DIR}/gpio_sim_drive.c)
  target_link_libraries(gpio_sim_drive ds_drivers_gpio)
  add_test(NAME hw/gpio-sim COMMAND sh ${CMAKE_CURRENT_LIST_DIR}/gpio_sim.sh $<TARGET_FILE:gpio_sim_drive>)
  set_tests_properties(hw/gpio-sim PROPERTIES LABELS "hw;nosan" SKIP_RETURN_CODE 77 TIMEOUT 60)
endif()
