# Light transport (drivers/sim/transport.cmake): optics, Monte Carlo, diffusion, PSF cache.
# Each program asserts against closed forms, published tables or a differently computed model.
if(TARGET ds_sim_transport)
  foreach(_ds_tr optics mc diffusion cache)
    if(EXISTS ${CMAKE_CURRENT_LIST_DIR}/transport_${_ds_tr}.c)
      add_executable(test_transport_${_ds_tr} ${CMAKE_CURRENT_LIST_DIR}/transport_${_ds_tr}.c)
      target_link_libraries(test_transport_${_ds_tr} PRIVATE ds_sim_transport)
      add_test(NAME sim/transport_${_ds_tr} COMMAND test_transport_${_ds_tr})
      set_tests_properties(sim/transport_${_ds_tr} PROPERTIES LABELS sim TIMEOUT 120)
    endif()
  endforeach()
endif()
