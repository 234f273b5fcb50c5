# The floors of the build. A target sees the headers of its own layer and of the layers it
# links, nothing else, so that an include that runs up a floor (proc/ including a driver, a
# driver including the daemon) fails to compile instead of becoming a habit.
#
# Each layer's headers are reached through a folder of the build tree that holds one symlink,
# ${DS_INCLUDE_ROOT}/<id>/<layer> -> ${CMAKE_SOURCE_DIR}/<layer>, so includes keep their
# source-tree spelling ("proc/image.h", "daemon/acquire/sequencer.h"). ds_layer () at the end of
# a layer's CMakeLists.txt puts that folder on every target defined there as a PUBLIC include
# directory: whoever links one of them sees the layer, whoever does not cannot.
#
# Layers, bottom up: proc; drivers/sim, drivers/core, then the backends and labsim; in daemon/,
# protocol, config, operating and output, then acquire, then service; ctl beside service; the
# tests above everything.
set(DS_INCLUDE_ROOT ${CMAKE_BINARY_DIR}/include)
set(DS_LAYERS
  proc
  drivers/sim drivers/core drivers/simdev drivers/aravis drivers/modbus drivers/gpio drivers/labsim
  daemon/protocol daemon/config daemon/operating daemon/output daemon/acquire daemon/service daemon/ctl
  tests)

# <layer> -> the folder id under DS_INCLUDE_ROOT ("daemon/acquire" -> "daemon_acquire").
function(ds_layer_dir layer out)
  string(REPLACE "/" "_" _id ${layer})
  set(${out} ${DS_INCLUDE_ROOT}/${_id} PARENT_SCOPE)
endfunction()

foreach(_layer ${DS_LAYERS})
  ds_layer_dir(${_layer} _dir)
  get_filename_component(_parent ${_dir}/${_layer} DIRECTORY)
  file(MAKE_DIRECTORY ${_parent})
  file(CREATE_LINK ${CMAKE_SOURCE_DIR}/${_layer} ${_dir}/${_layer} SYMBOLIC)
  # __FILE__ of a header reached through the link names it as in the source tree, as
  # -fmacro-prefix-map does for the sources (no build path in an installed binary). Given after
  # the source tree's map so that it wins where the build tree lies inside the source tree.
  add_compile_options(-fmacro-prefix-map=${_dir}/=)
endforeach()

# Generated headers (build_info.h, the embedded scene, page and camera description): private to
# the targets of the layers, which are the only ones that include them.
set(DS_GENERATED_DIR ${CMAKE_BINARY_DIR}/generated)

# ds_layer(<layer>): every library and program defined in the calling CMakeLists.txt belongs to
# <layer>: it exposes the layer's headers to what links it and sees the generated headers.
function(ds_layer layer)
  ds_layer_dir(${layer} _dir)
  get_property(_targets DIRECTORY PROPERTY BUILDSYSTEM_TARGETS)
  foreach(_t ${_targets})
    get_target_property(_type ${_t} TYPE)
    if(_type STREQUAL "INTERFACE_LIBRARY")
      target_include_directories(${_t} INTERFACE ${_dir})
    elseif(_type MATCHES "LIBRARY$|EXECUTABLE")
      target_include_directories(${_t} PUBLIC ${_dir} PRIVATE ${DS_GENERATED_DIR})
    endif()
  endforeach()
endfunction()

# ds_layer_headers(<target> <layer>): <target> sees <layer>'s headers without linking it, for a
# header-only contract between the two (a wire format both ends speak).
function(ds_layer_headers target layer)
  ds_layer_dir(${layer} _dir)
  target_include_directories(${target} PRIVATE ${_dir})
endfunction()
