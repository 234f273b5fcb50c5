# The renderer, its stages (one file each), the sensor model, and the descatter-sim tool.
target_sources(ds_sim PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/renderer.c
  ${CMAKE_CURRENT_LIST_DIR}/sensor.c
  ${CMAKE_CURRENT_LIST_DIR}/stage_pattern.c
  ${CMAKE_CURRENT_LIST_DIR}/stage_boundary.c
  ${CMAKE_CURRENT_LIST_DIR}/stage_ballistic.c
  ${CMAKE_CURRENT_LIST_DIR}/stage_objects.c
  ${CMAKE_CURRENT_LIST_DIR}/stage_scattering.c
  ${CMAKE_CURRENT_LIST_DIR}/stage_ambient.c
  ${CMAKE_CURRENT_LIST_DIR}/stage_sensor.c)
add_executable(descatter-sim ${CMAKE_CURRENT_LIST_DIR}/descatter_sim.c)
target_link_libraries(descatter-sim PRIVATE ds_sim)
install(TARGETS descatter-sim RUNTIME DESTINATION bin)
