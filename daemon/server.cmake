# The socket server half of descatterd (listeners, connections, fan-out).
add_library(ds_server STATIC ${CMAKE_CURRENT_LIST_DIR}/connection.c ${CMAKE_CURRENT_LIST_DIR}/server.c)
target_link_libraries(ds_server PUBLIC ds_protocol PkgConfig::GLIB PkgConfig::JSONGLIB PkgConfig::SYSTEMD)
target_compile_definitions(ds_server PRIVATE PROJECT_VERSION="${PROJECT_VERSION}")
