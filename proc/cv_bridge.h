/* The only door to OpenCV (C++). Plain C types, no GLib, no exceptions across it:
 * every function returns 0 on success or -1 with a message in err. Used for what OpenCV
 * does well: image files, DFT convolution, resizing, colour maps; plus an independent
 * OpenCV implementation of max/min separation that tests and benchmarks compare against. */
#pragma once
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

enum { DS_CV_U8 = 1, DS_CV_U16 = 2, DS_CV_F32 = 3 };

typedef struct {
  int width, height;
  int type;       /* DS_CV_U8, DS_CV_U16 or DS_CV_F32, one channel */
  size_t stride;  /* bytes per row */
  void *data;
} DsCvView;

/* Decodes a file. On success *data is malloc()ed, tightly packed (stride = width*size) and
 * owned by the caller (free()). A multi-channel file whose channels are equal is reduced to
 * one channel; one whose channels differ fails, and err says so. */
int ds_cv_imread (const char *path, int *width, int *height, int *type, void **data,
                  char *err, size_t errlen);

/* Encodes by the extension of path (which must be one OpenCV knows). */
int ds_cv_imwrite (const char *path, const DsCvView *image, char *err, size_t errlen);

enum { DS_CV_BORDER_ZERO = 0, DS_CV_BORDER_REFLECT = 1, DS_CV_BORDER_WRAP = 2 };

/* dst = src (*) kernel, true convolution (kernel flipped), same size as src, float32.
 * The kernel's centre is at (kw/2, kh/2). OpenCV switches to a DFT for large kernels.
 * DS_CV_BORDER_WRAP treats the image as periodic (exact for periodic stripe patterns). */
int ds_cv_convolve_f32 (const DsCvView *src, const DsCvView *kernel, int border,
                        DsCvView *dst, char *err, size_t errlen);

/* Repeated "valid" convolutions of float32 images of one size with fixed kernels through the
 * DFT: the plan holds the kernels' spectra (computed once), applying it only transforms the
 * images. All kernels are float32, square, of one odd side k with their centre at (k/2, k/2).
 * dst is (width - k + 1) x (height - k + 1): dst(x, y) = sum over offsets (dx, dy) in
 * [-k/2, k/2]^2 of K(k/2 + dx, k/2 + dy) src(x + k/2 - dx, y + k/2 - dy), the true convolution
 * where the kernel stays inside src (no border rule needed). Apply is thread-safe. */
typedef struct DsCvConvPlan DsCvConvPlan;
DsCvConvPlan *ds_cv_conv_plan_new (int width, int height, const DsCvView *kernels, int n_kernels,
                                   char *err, size_t errlen);
/* dst = sum over i of kernel i (*) srcs[i], for the i whose srcs[i].data is not NULL (at least
 * one); srcs has n_kernels views of width x height. */
int ds_cv_conv_plan_apply (const DsCvConvPlan *plan, const DsCvView *srcs, DsCvView *dst,
                           char *err, size_t errlen);
void ds_cv_conv_plan_free (DsCvConvPlan *plan);

/* Resizes a float32 image with area averaging (downscale) or bilinear (upscale). */
int ds_cv_resize_f32 (const DsCvView *src, DsCvView *dst, char *err, size_t errlen);

/* Maps an 8-bit grey image through the "inferno" colour map to an 8-bit BGR file at path. */
int ds_cv_write_colormap (const char *path, const DsCvView *grey8, char *err, size_t errlen);

/* Reference max/min separation written the OpenCV way (cv::max, cv::min, cv::subtract on
 * u16 frames): direct = max - min, global = 2 * min, both float32, tight stride. */
int ds_cv_separate_maxmin_u16 (const uint16_t *const *frames, int n, int width, int height,
                               size_t stride, float *direct, float *global,
                               char *err, size_t errlen);

#ifdef __cplusplus
}
#endif
