# The wire protocol (no I/O): shared by descatterd, descatterctl, tests and the fuzzer.
add_library(ds_protocol STATIC ${CMAKE_CURRENT_LIST_DIR}/protocol.c)
target_link_libraries(ds_protocol PUBLIC PkgConfig::GLIB PkgConfig::JSONGLIB ${MATH_LIBRARY})
