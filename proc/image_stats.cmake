target_sources(ds_proc PRIVATE ${CMAKE_CURRENT_LIST_DIR}/image_stats.c)
