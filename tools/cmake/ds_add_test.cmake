# ds_add_test (): one test, and the program it runs, in one call, so that a test folder's
# CMakeLists.txt is a table of tests. Every test gets the same properties from the same place:
#
#   ds_add_test(NAME <area>/<name>          ctest name; <area> is the default label
#     [TARGET <exe>]                        the program (default: test_<name of first source>)
#     [SOURCES <file>...]                   build TARGET from these (it sees the tests' headers,
#                                           ds_test_tree); without, TARGET must exist
#     [LIBS <lib>...]                       linked to TARGET
#     [DEFINITIONS <def>...]                compile definitions of TARGET
#     [DEPENDS <target>...]                 built before TARGET (programs the test starts)
#     [COMMAND <cmd>...]                    run this instead of TARGET (scripts)
#     [ARGS <arg>...]                       appended to the command
#     [NETNS]                               run through tests/drivers/netns_run.sh (a private
#                                           network namespace where the machine allows one)
#     [LABELS <label>...]                   default: <area>
#     [TIMEOUT <s>] [RESOURCE_LOCK <lock>...] [SKIP_RETURN_CODE <n>]
#     [ENV <VAR=value>...]                  put before DS_TEST_ENV
#     [NO_DATA_ENV])                        leave DS_TEST_ENV out (a test that reads no data)
#
# Rules it keeps: anything that binds the GigE Vision port 3956 passes NETNS and
# RESOURCE_LOCK gige_port_3956; programs from the build tree find the data through DS_TEST_ENV,
# as installed ones find it under the data dir.
function(ds_add_test)
  cmake_parse_arguments(PARSE_ARGV 0 T "NETNS;NO_DATA_ENV"
    "NAME;TARGET;TIMEOUT;SKIP_RETURN_CODE"
    "SOURCES;LIBS;DEFINITIONS;DEPENDS;COMMAND;ARGS;LABELS;RESOURCE_LOCK;ENV")
  if(T_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "ds_add_test(${T_NAME}): unknown arguments ${T_UNPARSED_ARGUMENTS}")
  endif()
  if(NOT T_TARGET AND T_SOURCES)
    list(GET T_SOURCES 0 _first)
    get_filename_component(_first ${_first} NAME_WE)
    if(_first MATCHES "^test_")
      set(T_TARGET ${_first})
    else()
      set(T_TARGET test_${_first})
    endif()
  endif()
  if(T_SOURCES)
    add_executable(${T_TARGET} ${T_SOURCES})
    target_link_libraries(${T_TARGET} PRIVATE ds_test_tree)
  endif()
  if(T_LIBS)
    target_link_libraries(${T_TARGET} PRIVATE ${T_LIBS})
  endif()
  if(T_DEFINITIONS)
    target_compile_definitions(${T_TARGET} PRIVATE ${T_DEFINITIONS})
  endif()
  if(T_DEPENDS)
    add_dependencies(${T_TARGET} ${T_DEPENDS})
  endif()

  if(T_COMMAND)
    set(_cmd ${T_COMMAND})
  else()
    set(_cmd $<TARGET_FILE:${T_TARGET}>)
  endif()
  if(T_NETNS)
    set(_cmd ${DS_NETNS_RUN} ${_cmd})
  endif()
  add_test(NAME ${T_NAME} COMMAND ${_cmd} ${T_ARGS})

  if(NOT T_LABELS)
    string(REGEX REPLACE "/.*" "" T_LABELS ${T_NAME})
  endif()
  set_property(TEST ${T_NAME} PROPERTY LABELS ${T_LABELS})
  if(T_TIMEOUT)
    set_property(TEST ${T_NAME} PROPERTY TIMEOUT ${T_TIMEOUT})
  endif()
  if(T_RESOURCE_LOCK)
    set_property(TEST ${T_NAME} PROPERTY RESOURCE_LOCK ${T_RESOURCE_LOCK})
  endif()
  if(DEFINED T_SKIP_RETURN_CODE)
    set_property(TEST ${T_NAME} PROPERTY SKIP_RETURN_CODE ${T_SKIP_RETURN_CODE})
  endif()
  set(_env ${T_ENV})
  if(NOT T_NO_DATA_ENV)
    list(APPEND _env "${DS_TEST_ENV}")
  endif()
  if(_env)
    set_property(TEST ${T_NAME} PROPERTY ENVIRONMENT ${_env})
  endif()
endfunction()
