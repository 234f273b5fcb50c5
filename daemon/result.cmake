# Results and their settings: shared by the acquisition thread, the server side and the spool.
add_library(ds_result STATIC ${CMAKE_CURRENT_LIST_DIR}/capture_settings.c ${CMAKE_CURRENT_LIST_DIR}/result.c)
target_link_libraries(ds_result PUBLIC ds_proc ds_config ds_protocol PkgConfig::JSONGLIB)
