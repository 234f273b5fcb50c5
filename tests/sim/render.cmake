# Scene parser, sensor model, renderer and descatter-sim tests (drivers/sim).
foreach(t scene_parse sensor_ptc renderer_stages renderer_cli)
  if(EXISTS ${CMAKE_CURRENT_LIST_DIR}/${t}.c)
    add_executable(test_sim_${t} ${CMAKE_CURRENT_LIST_DIR}/${t}.c)
    target_link_libraries(test_sim_${t} PRIVATE ds_sim)
    target_compile_definitions(test_sim_${t} PRIVATE DS_SCENES_DIR="${CMAKE_SOURCE_DIR}/etc/scenes"
                               DS_SIM_BIN="$<TARGET_FILE:descatter-sim>")
    add_dependencies(test_sim_${t} descatter-sim)
    add_test(NAME sim/${t} COMMAND test_sim_${t})
    # Monte Carlo kernels go to a cache inside the build tree, never the user's.
    set_tests_properties(sim/${t} PROPERTIES LABELS sim ENVIRONMENT "XDG_CACHE_HOME=${CMAKE_BINARY_DIR}/test-cache")
  endif()
endforeach()
