# The scene parser's fuzz target needs the simulator library.
set(DS_FUZZ_LIBS_scene ds_sim)
