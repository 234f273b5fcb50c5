# The floors of the build. A target sees the headers of its own layer and of the layers it
# links, nothing else, so that an include that runs up a floor (proc/ including a driver, a
# driver including the daemon) fails to compile instead of becoming a habit.
#
# Each layer's headers are reached through a folder of the build tree that holds one symlink,
# ${DS_INCLUDE_ROOT}/<id>/<layer> -> ${CMAKE_SOURCE_DIR}/<layer>, so includes keep their
# source-tree spelling ("proc/image.h", "daemon/acquire/sequencer.h"). ds_layer () at the end of
# a layer's CMakeLists.txt makes that folder and puts it on every target defined there as a
# PUBLIC include directory: whoever links one of them sees the layer, whoever does not cannot.
# A new folder of code ends its CMakeLists.txt with ds_layer(<folder>) and nothing else.
#
# Layers, bottom up: proc; drivers/sim, drivers/core, then the backends and labsim; in daemon/,
# protocol, config, operating and output, then acquire, then service; ctl beside service; the
# tests above everything (build/layering-* check a few of these floors).
set(DS_INCLUDE_ROOT ${CMAKE_BINARY_DIR}/include)

# Generated headers (build_info.h, the embedded scene, page and camera description): private to
# the targets of the layers, which are the only ones that include them.
set(DS_GENERATED_DIR ${CMAKE_BINARY_DIR}/generated)

# <layer> -> the folder under DS_INCLUDE_ROOT that holds its link ("daemon/acquire" ->
# ".../daemon_acquire"), (re)made at each configure.
function(ds_layer_dir layer out)
  string(REPLACE "/" "_" _id ${layer})
  set(_dir ${DS_INCLUDE_ROOT}/${_id})
  get_filename_component(_parent ${_dir}/${layer} DIRECTORY)
  file(MAKE_DIRECTORY ${_parent})
  file(CREATE_LINK ${CMAKE_SOURCE_DIR}/${layer} ${_dir}/${layer} SYMBOLIC)
  set(${out} ${_dir} PARENT_SCOPE)
endfunction()

# ds_layer(<layer>): every library and program defined in the calling CMakeLists.txt belongs to
# <layer>: it exposes the layer's headers to what links it and sees the generated headers.
# __FILE__ of a header reached through the link names it as in the source tree, as the global
# -fmacro-prefix-map does for the sources (no build path in an installed binary); the option
# travels with the include directory, after the global one, so it wins where the build tree
# lies inside the source tree (GCC takes the last matching map, clang the longest).
function(ds_layer layer)
  ds_layer_dir(${layer} _dir)
  set(_map -fmacro-prefix-map=${_dir}/=)
  get_property(_targets DIRECTORY PROPERTY BUILDSYSTEM_TARGETS)
  foreach(_t ${_targets})
    get_target_property(_type ${_t} TYPE)
    if(_type STREQUAL "INTERFACE_LIBRARY")
      target_include_directories(${_t} INTERFACE ${_dir})
      target_compile_options(${_t} INTERFACE ${_map})
    elseif(_type MATCHES "LIBRARY$|EXECUTABLE")
      target_include_directories(${_t} PUBLIC ${_dir} PRIVATE ${DS_GENERATED_DIR})
      target_compile_options(${_t} PUBLIC ${_map})
    endif()
  endforeach()
endfunction()

# ds_layer_headers(<target> <layer>): <target> sees <layer>'s headers without linking it, for a
# header-only contract between the two (a wire format both ends speak).
function(ds_layer_headers target layer)
  ds_layer_dir(${layer} _dir)
  target_include_directories(${target} PRIVATE ${_dir})
  target_compile_options(${target} PRIVATE -fmacro-prefix-map=${_dir}/=)
endfunction()
