/* The lab's camera: Aravis's GigE Vision fake camera (ArvGvFakeCamera, real GVCP/GVSP on UDP
 * port 3956 of one address) whose images come from the scene renderer, lit with whatever the
 * illuminator shows at the moment the frame is filled (right after its trigger).
 *
 * Pixel formats: Mono16 carries the sensor's DN unchanged (bit depth <= 16); Mono8 the top
 * 8 bits; RGB8 and the Bayer formats of the fake camera's XML get the Mono8 value in every
 * sample. The ROI (Width, Height, OffsetX, OffsetY) crops the rendered frame; pixels outside
 * the scene are 0. Gain is 0 dB (the fake camera's XML has no gain feature).
 *
 * Threads: new/vanish/appear/free on the main thread (the one running the default main
 * context, which the vanish timers use); frames are filled on Aravis's camera thread. */
#pragma once
#include <glib.h>

#include "drivers/sim/renderer.h"

G_BEGIN_DECLS

typedef struct DsLabCamera DsLabCamera;

/* Fills req->phase, req->n_phases and req->illuminator_on with what is lit now. Called on the
 * camera thread. */
typedef void (*DsLabIlluminationFunc) (gpointer user_data, DsRenderRequest *req);

typedef struct {
  const char *address;       /* IPv4 address to serve on, e.g. "127.0.0.1" */
  const char *serial;        /* device serial number (NULL: "DSLAB01") */
  double gvsp_lost_ratio;    /* fraction of GVSP packets not sent, 0..1 */
  guint vanish_after_frames; /* 0: never; else the camera disappears after this many frames ... */
  double vanish_for_s;       /* ... for this long, then comes back (once) */
  guint64 seed;              /* noise seed of the first frame; +1 per frame */
} DsLabCameraConfig;

/* renderer is borrowed and must outlive the camera. Fails (G_IO_ERROR) when the fake camera
 * cannot serve on the address (e.g. port 3956 in use). */
DsLabCamera *ds_lab_camera_new (const DsLabCameraConfig *config, const DsRenderer *renderer,
                                DsLabIlluminationFunc illumination, gpointer user_data,
                                GError **error);
guint64 ds_lab_camera_frames (DsLabCamera *camera);   /* frames filled so far */
gboolean ds_lab_camera_present (DsLabCamera *camera); /* FALSE while vanished */
void ds_lab_camera_free (DsLabCamera *camera);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsLabCamera, ds_lab_camera_free)

G_END_DECLS
