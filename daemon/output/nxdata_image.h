/* NXdata groups of images for the NeXus writers (hdf5_set.c, hdf5_run.c): x and y axis
 * datasets in micrometres on the object plane when the pixel size is known (the result
 * metadata's pixel_size_um, ds_output_pixel_size_um), pixel indices otherwise, and the NXdata
 * attributes that tie them to the signal (axes, AXISNAME_indices), so that silx, h5web and
 * NeXpy plot the image with its scale. Private to daemon/output. Any thread. */
#pragma once
#include <glib.h>
#include <hdf5.h>

#include "proc/image.h"

G_BEGIN_DECLS

/* Writes the datasets `y` (height) and `x` (width) into group: their centres at i * pixel_size_um
 * with units "um", or the indices i with units "pixel" when pixel_size_um is NAN; and the group's
 * axes attribute: lead_axis (NULL: no leading dimension; "." or a dataset name of the group)
 * followed by "y" and "x", with y_indices and x_indices (and lead_axis_indices when it names a
 * dataset). The image's first pixel is at 0. */
gboolean ds_nxdata_image_axes (hid_t group, guint width, guint height, double pixel_size_um, const char *lead_axis);

/* Marks an image (2-D) or image stack (3-D) signal dataset as such (interpretation "image"), so
 * that readers show a stack as images rather than curves. */
gboolean ds_nxdata_mark_image (hid_t dataset);

/* An NXdata group `name` whose signal "data" is img (a result plane: units and long name by
 * plane name, the mask's legend), with its x and y axes: the layout NeXus viewers plot. */
gboolean ds_nxdata_image (hid_t parent, const char *name, const DsImage *img, const char *plane, double pixel_size_um);

G_END_DECLS
