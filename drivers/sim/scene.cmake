# Scene files (docs/scene-format.md).
target_sources(ds_sim PRIVATE ${CMAKE_CURRENT_LIST_DIR}/scene.c)
