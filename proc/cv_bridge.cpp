// The project's single C++ file: plain C entry points over OpenCV. No exception may cross
// into C, so every entry point catches everything and reports through err.
#include "proc/cv_bridge.h"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <vector>

namespace {

/* The attribute lets -Wformat check callers (and lets clang accept the vsnprintf below). */
void set_err (char *err, size_t errlen, const char *fmt, ...) __attribute__ ((format (printf, 3, 4)));

void
set_err (char *err, size_t errlen, const char *fmt, ...)
{
  if (!err || errlen == 0)
    return;
  va_list ap;
  va_start (ap, fmt);
  std::vsnprintf (err, errlen, fmt, ap);
  va_end (ap);
}

int
cv_depth (int type)
{
  switch (type) {
  case DS_CV_U8: return CV_8U;
  case DS_CV_U16: return CV_16U;
  case DS_CV_F32: return CV_32F;
  default: return -1;
  }
}

bool
wrap (const DsCvView *v, cv::Mat &out, char *err, size_t errlen)
{
  int depth = v ? cv_depth (v->type) : -1;
  if (!v || depth < 0 || v->width <= 0 || v->height <= 0 || !v->data) {
    set_err (err, errlen, "invalid image view");
    return false;
  }
  out = cv::Mat (v->height, v->width, CV_MAKETYPE (depth, 1), v->data, v->stride);
  return true;
}

/* Runs body, the part of an entry point that may throw (OpenCV's cv::Exception,
 * std::bad_alloc), and turns any exception into err and the entry point's failure value. */
template <typename R, typename Body>
R
guarded (char *err, size_t errlen, R failed, Body body)
{
  try {
    return body ();
  } catch (const std::exception &e) {
    set_err (err, errlen, "%s", e.what ());
  } catch (...) {
    set_err (err, errlen, "unknown OpenCV failure");
  }
  return failed;
}

} // namespace

extern "C" int
ds_cv_imread (const char *path, int *width, int *height, int *type, void **data, char *err,
              size_t errlen)
{
  return guarded (err, errlen, -1, [&] {
    cv::Mat m = cv::imread (path, cv::IMREAD_UNCHANGED | cv::IMREAD_ANYDEPTH);
    if (m.empty ()) {
      set_err (err, errlen, "not a readable image (unknown format, truncated or corrupt)");
      return -1;
    }
    int t;
    switch (m.depth ()) {
    case CV_8U: t = DS_CV_U8; break;
    case CV_16U: t = DS_CV_U16; break;
    case CV_32F: t = DS_CV_F32; break;
    default:
      set_err (err, errlen, "unsupported sample depth (OpenCV depth %d); want 8/16-bit or float32",
               m.depth ());
      return -1;
    }
    if (m.channels () > 1) {
      std::vector<cv::Mat> ch;
      cv::split (m, ch);
      // Alpha (4th channel) does not count; the colour channels must agree.
      int colour = m.channels () == 4 ? 3 : m.channels ();
      for (int c = 1; c < colour; c++) {
        cv::Mat diff;
        cv::compare (ch[0], ch[c], diff, cv::CMP_NE);
        if (cv::countNonZero (diff) != 0) {
          set_err (err, errlen, "colour image with differing channels; save it as greyscale");
          return -1;
        }
      }
      m = ch[0];
    }
    if (!m.isContinuous ())
      m = m.clone ();
    size_t bytes = m.total () * m.elemSize ();
    void *buf = std::malloc (bytes ? bytes : 1);
    if (!buf) {
      set_err (err, errlen, "out of memory for %zu bytes", bytes);
      return -1;
    }
    std::memcpy (buf, m.data, bytes);
    *width = m.cols;
    *height = m.rows;
    *type = t;
    *data = buf;
    return 0;
  });
}

extern "C" int
ds_cv_imwrite (const char *path, const DsCvView *image, char *err, size_t errlen)
{
  return guarded (err, errlen, -1, [&] {
    cv::Mat m;
    if (!wrap (image, m, err, errlen))
      return -1;
    if (!cv::imwrite (path, m)) {
      set_err (err, errlen, "encoder refused the image (format does not support this depth?)");
      return -1;
    }
    return 0;
  });
}

extern "C" int
ds_cv_convolve_f32 (const DsCvView *src, const DsCvView *kernel, int border, DsCvView *dst,
                    char *err, size_t errlen)
{
  return guarded (err, errlen, -1, [&] {
    cv::Mat s, k, d;
    if (!wrap (src, s, err, errlen) || !wrap (kernel, k, err, errlen) || !wrap (dst, d, err, errlen))
      return -1;
    if (s.depth () != CV_32F || k.depth () != CV_32F || d.depth () != CV_32F || s.size () != d.size ()) {
      set_err (err, errlen, "convolution wants float32 source, kernel and same-size destination");
      return -1;
    }
    cv::Mat kflip;
    cv::flip (k, kflip, -1); // filter2D correlates; flipping makes it a convolution
    cv::Point anchor (k.cols - 1 - k.cols / 2, k.rows - 1 - k.rows / 2);
    if (border == DS_CV_BORDER_WRAP) {
      // filter2D has no periodic border: pad by wrapping, filter, crop.
      int px = k.cols, py = k.rows;
      cv::Mat padded;
      cv::copyMakeBorder (s, padded, py, py, px, px, cv::BORDER_WRAP);
      cv::Mat out;
      cv::filter2D (padded, out, CV_32F, kflip, anchor, 0, cv::BORDER_CONSTANT);
      out (cv::Rect (px, py, s.cols, s.rows)).copyTo (d);
    } else {
      int b = border == DS_CV_BORDER_REFLECT ? cv::BORDER_REFLECT : cv::BORDER_CONSTANT;
      cv::filter2D (s, d, CV_32F, kflip, anchor, 0, b);
    }
    return 0;
  });
}

struct DsCvConvPlan {
  int width, height, side, dft_w, dft_h;
  std::vector<cv::Mat> spectra; // CCS-packed spectra of the kernels, wrapped to put the centre at (0, 0)
};

extern "C" DsCvConvPlan *
ds_cv_conv_plan_new (int width, int height, const DsCvView *kernels, int n_kernels, char *err, size_t errlen)
{
  return guarded (err, errlen, static_cast<DsCvConvPlan *> (nullptr), [&] () -> DsCvConvPlan * {
    if (n_kernels < 1 || !kernels) {
      set_err (err, errlen, "convolution plan: no kernel");
      return nullptr;
    }
    int side = kernels[0].width;
    if (side < 1 || side % 2 == 0 || width < side || height < side) {
      set_err (err, errlen, "convolution plan: kernel %dx%d must be odd, square and fit in %dx%d", kernels[0].width,
               kernels[0].height, width, height);
      return nullptr;
    }
    auto plan = std::make_unique<DsCvConvPlan> (); // freed if anything below throws
    plan->width = width;
    plan->height = height;
    plan->side = side;
    // A circular convolution of this size equals the linear one wherever the kernel stays inside
    // the image, which is all dst asks for.
    plan->dft_w = cv::getOptimalDFTSize (width);
    plan->dft_h = cv::getOptimalDFTSize (height);
    int r = side / 2;
    for (int i = 0; i < n_kernels; i++) {
      cv::Mat k;
      if (!wrap (&kernels[i], k, err, errlen) || k.depth () != CV_32F || k.cols != side || k.rows != side) {
        set_err (err, errlen, "convolution plan: kernel %d is not float32 %dx%d", i, side, side);
        return nullptr;
      }
      cv::Mat wrapped = cv::Mat::zeros (plan->dft_h, plan->dft_w, CV_32F);
      for (int y = 0; y < side; y++)
        for (int x = 0; x < side; x++) {
          int wy = (y - r + plan->dft_h) % plan->dft_h, wx = (x - r + plan->dft_w) % plan->dft_w;
          wrapped.at<float> (wy, wx) += k.at<float> (y, x);
        }
      cv::Mat spec;
      cv::dft (wrapped, spec, 0);
      plan->spectra.push_back (spec);
    }
    return plan.release ();
  });
}

extern "C" int
ds_cv_conv_plan_apply (const DsCvConvPlan *plan, const DsCvView *srcs, DsCvView *dst, char *err, size_t errlen)
{
  return guarded (err, errlen, -1, [&] {
    cv::Mat d;
    int r = plan->side / 2;
    if (!wrap (dst, d, err, errlen) || d.depth () != CV_32F || d.cols != plan->width - 2 * r ||
        d.rows != plan->height - 2 * r) {
      set_err (err, errlen, "convolution: destination must be float32 %dx%d", plan->width - 2 * r,
               plan->height - 2 * r);
      return -1;
    }
    cv::Mat sum, padded (plan->dft_h, plan->dft_w, CV_32F), spec, product;
    for (size_t i = 0; i < plan->spectra.size (); i++) {
      if (!srcs[i].data)
        continue;
      cv::Mat s;
      if (!wrap (&srcs[i], s, err, errlen) || s.depth () != CV_32F || s.cols != plan->width ||
          s.rows != plan->height) {
        set_err (err, errlen, "convolution: source %zu must be float32 %dx%d", i, plan->width, plan->height);
        return -1;
      }
      padded.setTo (0);
      s.copyTo (padded (cv::Rect (0, 0, s.cols, s.rows)));
      cv::dft (padded, spec, 0, s.rows);
      if (sum.empty ())
        cv::mulSpectrums (spec, plan->spectra[i], sum, 0);
      else {
        cv::mulSpectrums (spec, plan->spectra[i], product, 0);
        sum += product;
      }
    }
    if (sum.empty ()) {
      set_err (err, errlen, "convolution: no source");
      return -1;
    }
    cv::Mat out;
    cv::dft (sum, out, cv::DFT_INVERSE | cv::DFT_SCALE | cv::DFT_REAL_OUTPUT);
    out (cv::Rect (r, r, d.cols, d.rows)).copyTo (d);
    return 0;
  });
}

extern "C" void
ds_cv_conv_plan_free (DsCvConvPlan *plan)
{
  delete plan;
}

extern "C" int
ds_cv_resize_f32 (const DsCvView *src, DsCvView *dst, char *err, size_t errlen)
{
  return guarded (err, errlen, -1, [&] {
    cv::Mat s, d;
    if (!wrap (src, s, err, errlen) || !wrap (dst, d, err, errlen))
      return -1;
    bool down = d.cols < s.cols || d.rows < s.rows;
    cv::resize (s, d, d.size (), 0, 0, down ? cv::INTER_AREA : cv::INTER_LINEAR);
    return 0;
  });
}

extern "C" int
ds_cv_write_colormap (const char *path, const DsCvView *grey8, char *err, size_t errlen)
{
  return guarded (err, errlen, -1, [&] {
    cv::Mat g, c;
    if (!wrap (grey8, g, err, errlen))
      return -1;
    if (g.depth () != CV_8U) {
      set_err (err, errlen, "colour map wants an 8-bit image");
      return -1;
    }
    cv::applyColorMap (g, c, cv::COLORMAP_INFERNO);
    if (!cv::imwrite (path, c)) {
      set_err (err, errlen, "encoder refused the colour-mapped image");
      return -1;
    }
    return 0;
  });
}

extern "C" int
ds_cv_separate_maxmin_u16 (const uint16_t *const *frames, int n, int width, int height,
                           size_t stride, float *direct, float *global, char *err, size_t errlen)
{
  return guarded (err, errlen, -1, [&] {
    if (n < 1 || width <= 0 || height <= 0) {
      set_err (err, errlen, "invalid separation arguments");
      return -1;
    }
    cv::Mat mx (height, width, CV_16U, const_cast<uint16_t *> (frames[0]), stride);
    cv::Mat mn = mx.clone ();
    mx = mx.clone ();
    for (int i = 1; i < n; i++) {
      cv::Mat f (height, width, CV_16U, const_cast<uint16_t *> (frames[i]), stride);
      cv::max (mx, f, mx);
      cv::min (mn, f, mn);
    }
    cv::Mat d16, d (height, width, CV_32F, direct), g (height, width, CV_32F, global);
    cv::subtract (mx, mn, d16);
    d16.convertTo (d, CV_32F);
    mn.convertTo (g, CV_32F, 2.0);
    return 0;
  });
}
