# cmake -DCC=<compiler> -DINCLUDES=<dirs> -DSOURCE_DIR=<tree> -DWORK=<dir> -DCASES=<cases> -P check_layer.cmake
#
# Preprocesses one include at a time with exactly the include directories a target compiles
# with (INCLUDES), and checks what that target may see. CASES is a list of
#   sees:<header>   <header> ("proc/image.h") must preprocess: the context works at all
#   blind:<layer>   a header of <layer> must not be found: including it is a build error
# For blind cases the header is the first *.h of <layer> in the source tree, so that renaming a
# header keeps the case meaningful; a layer without headers fails the test rather than passing
# it unseen.
foreach(_v CC INCLUDES SOURCE_DIR WORK CASES)
  if(NOT DEFINED ${_v})
    message(FATAL_ERROR "check_layer.cmake: -D${_v}= missing")
  endif()
endforeach()
file(MAKE_DIRECTORY ${WORK})
set(_flags)
foreach(_dir ${INCLUDES})
  list(APPEND _flags -I${_dir})
endforeach()

set(_failed 0)
foreach(_case ${CASES})
  string(REPLACE ":" ";" _parts ${_case})
  list(GET _parts 0 _expect)
  list(GET _parts 1 _layer)
  if(_layer MATCHES "[.]h$")
    set(_headers ${_layer})
  else()
    file(GLOB _headers RELATIVE ${SOURCE_DIR} ${SOURCE_DIR}/${_layer}/*.h)
  endif()
  list(SORT _headers)
  if(NOT _headers)
    message(SEND_ERROR "${_case}: ${_layer} has no header to include")
    set(_failed 1)
    continue()
  endif()
  list(GET _headers 0 _header)
  set(_probe ${WORK}/probe.c)
  file(WRITE ${_probe} "#include \"${_header}\"\n")
  execute_process(COMMAND ${CC} -E ${_flags} ${_probe} -o ${WORK}/probe.i
                  RESULT_VARIABLE _rc OUTPUT_VARIABLE _out ERROR_VARIABLE _out)
  string(REGEX MATCH "${_header}'?:? *(No such file or directory|file not found)" _not_found "${_out}")
  if(_expect STREQUAL "sees" AND _rc EQUAL 0)
    message(STATUS "ok: sees ${_header}")
  elseif(_expect STREQUAL "blind" AND NOT _rc EQUAL 0 AND _not_found)
    message(STATUS "ok: #include \"${_header}\" fails: not on the include path")
  else()
    message(SEND_ERROR "${_case}: #include \"${_header}\" exited ${_rc}\n${_out}")
    set(_failed 1)
  endif()
endforeach()
if(_failed)
  message(FATAL_ERROR "layering broken (docs/conventions.md, tools/cmake/ds_layers.cmake)")
endif()
