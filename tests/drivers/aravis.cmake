# The Aravis backend against Aravis's GigE Vision fake camera on 127.0.0.1 (UDP 3956: one at a
# time). In-process with a fill pattern the test controls; and against arv-fake-gv-camera-0.8.
# Both run through netns_run.sh (a private loopback where the machine allows it) when it exists.
if(EXISTS ${CMAKE_CURRENT_LIST_DIR}/netns_run.sh)
  set(_ds_gige_wrap sh ${CMAKE_CURRENT_LIST_DIR}/netns_run.sh)
else()
  set(_ds_gige_wrap)
endif()

if(TARGET ds_drivers_aravis)
  add_executable(test_aravis_inprocess ${CMAKE_CURRENT_LIST_DIR}/aravis_inprocess.c)
  target_link_libraries(test_aravis_inprocess ds_drivers_aravis)
  add_test(NAME drivers/aravis-inprocess COMMAND ${_ds_gige_wrap} $<TARGET_FILE:test_aravis_inprocess>)
  set_tests_properties(drivers/aravis-inprocess PROPERTIES LABELS drivers TIMEOUT 120
                       RESOURCE_LOCK gige_port_3956)
endif()

# Debian's aravis-tools: the fake camera as a separate program.
find_program(DS_ARV_FAKE_GV_CAMERA arv-fake-gv-camera-0.8)
if(TARGET ds_drivers_aravis AND DS_ARV_FAKE_GV_CAMERA)
  add_executable(test_aravis_fake_program ${CMAKE_CURRENT_LIST_DIR}/aravis_fake_program.c)
  target_link_libraries(test_aravis_fake_program ds_drivers_aravis PkgConfig::GLIB)
  # -r is the GVSP packet loss of arv-fake-gv-camera-0.8 in packets per thousand.
  target_compile_definitions(test_aravis_fake_program PRIVATE
                             DS_ARV_FAKE_GV_CAMERA="${DS_ARV_FAKE_GV_CAMERA}" DS_ARV_FAKE_LOSS="50")
  add_test(NAME drivers/aravis-fake-program COMMAND ${_ds_gige_wrap} $<TARGET_FILE:test_aravis_fake_program>)
  set_tests_properties(drivers/aravis-fake-program PROPERTIES LABELS drivers TIMEOUT 120
                       RESOURCE_LOCK gige_port_3956)
endif()
