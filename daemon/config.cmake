# descatterd's configuration file parser.
add_library(ds_config STATIC ${CMAKE_CURRENT_LIST_DIR}/config.c)
target_link_libraries(ds_config PUBLIC PkgConfig::GLIB ${MATH_LIBRARY})
