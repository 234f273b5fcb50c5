# Render time per stage of each example scene at 1024x1024 (docs/scene-format.md). ctest: --quick.
add_executable(bench_render ${CMAKE_CURRENT_LIST_DIR}/render.c)
target_link_libraries(bench_render PRIVATE ds_sim)
target_compile_definitions(bench_render PRIVATE DS_SCENES_DIR="${CMAKE_SOURCE_DIR}/etc/scenes")
add_test(NAME bench/render COMMAND bench_render --quick --cache-dir ${CMAKE_BINARY_DIR}/psf-cache)
set_tests_properties(bench/render PROPERTIES LABELS bench)
