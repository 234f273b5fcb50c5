/* Building row loops for the vector units: functions marked DS_CLONES (memory-bound loops) or
 * DS_CLONES_WIDE (arithmetic) are compiled, on x86-64, for AVX2 (and AVX-512) besides the
 * baseline, and the loader picks the best the CPU has. Their bodies are DS_KERNEL functions
 * with restrict parameters, inlined into each clone. The files that hold such loops are
 * built with -ftree-vectorize (proc/CMakeLists.txt). */
#pragma once

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define DS_NO_CLONES 1 /* clang's spelling of __SANITIZE_ADDRESS__ */
#endif
#endif
#if defined(__x86_64__) && defined(__has_attribute) && !defined(DS_NO_CLONES)
#if __has_attribute(target_clones) && !defined(__SANITIZE_ADDRESS__)
/* Measured on the benchmark machine (AMD EPYC, tests/bench/separation): AVX-512 speeds up the
 * finalize rows (float maths) but slows the u16 fold (memory bound), so each gets its own list. */
#define DS_CLONES __attribute__ ((target_clones ("avx2", "default")))
#define DS_CLONES_WIDE __attribute__ ((target_clones ("arch=x86-64-v4", "avx2", "default")))
#endif
#endif
#ifndef DS_CLONES
#define DS_CLONES
#define DS_CLONES_WIDE
#endif
/* Kernel bodies take restrict parameters (which GCC honours, unlike restrict locals loaded
 * from a struct) and are inlined into each clone. */
#define DS_KERNEL static inline __attribute__ ((always_inline))
