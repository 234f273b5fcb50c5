# proc/ fuzz targets: pixel-format unpacking and phase folders.
set(DS_FUZZ_LIBS_pixfmt ds_proc)
set(DS_FUZZ_LIBS_phase_folder ds_proc)
