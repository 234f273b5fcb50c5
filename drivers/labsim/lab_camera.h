/* The lab's camera: Aravis's GigE Vision fake camera (ArvGvFakeCamera, real GVCP/GVSP on UDP
 * port 3956 of one address) described by labsim's own GenICam XML (labsim-camera.xml), whose
 * images come from the scene renderer, lit with whatever the illuminator showed at the frame's
 * trigger (rendered off the camera thread: lab_states.h, lab_camera_fill.h).
 *
 * Pixel formats: Mono8, Mono10, Mono12, Mono16, Mono10p, Mono12p, Mono12Packed, each carrying
 * the sensor's value less the low bits it lacks (lab_camera_fill.h says the byte layouts).
 * The ROI (Width in steps of 4, Height, OffsetX, OffsetY) crops the rendered frame. Gain is the
 * Gain feature in dB (0..24), exposure ExposureTime in µs.
 *
 * Trigger: TriggerMode On with TriggerSource Software (TriggerSoftware command) or Line0..3: a
 * frame per edge at that line input (ds_lab_camera_line_edge), rising or falling as
 * TriggerActivation says. descatter-labsim wires the projector's sync output or the simulated
 * GPIO chip's lines to these inputs (docs/drivers.md, "Wiring"). A software command with a line
 * source is ignored, as on a real camera.
 *
 * Threads: new/free on the main thread (the one running the default main context, which the
 * vanish timers use); frames are filled on Aravis's camera thread; triggers are routed on a
 * thread of the camera's own; ds_lab_camera_line_edge and the getters from any thread. */
#pragma once
#include <glib.h>

#include "drivers/sim/renderer.h"

G_BEGIN_DECLS

typedef struct DsLabCamera DsLabCamera;

/* Fills req->phase, req->n_phases, req->illuminator_on and req->period_px (0: the scene's) with
 * what is lit now. Called from labsim's camera threads, one at a time. */
typedef void (*DsLabIlluminationFunc) (gpointer user_data, DsRenderRequest *req);

typedef struct {
  const char *address;       /* IPv4 address to serve on, e.g. "127.0.0.1" */
  const char *serial;        /* device serial number (NULL: "DSLAB01") */
  double gvsp_lost_ratio;    /* fraction of GVSP packets not sent, 0..1 */
  guint vanish_after_frames; /* 0: never; else the camera disappears after this many frames ... */
  double vanish_for_s;       /* ... for this long, then comes back (once) */
  guint64 seed;              /* noise seed */
  gboolean noiseless;        /* frames are the rendered expectation, rounded (no sensor noise) */
  guint line_miss_every;     /* fault: every Nth accepted line trigger makes no frame */
  guint line_double_every;   /* fault: every Nth accepted line trigger makes two frames */
  const char *pixel_formats; /* NULL: every PixelFormat of labsim-camera.xml; else a comma list */
  double gain_max_db;        /* 0: the description's 24 dB */
} DsLabCameraConfig;

typedef struct {
  guint64 software;          /* software triggers that made a frame */
  guint64 software_ignored;  /* software triggers while a line was the source */
  guint64 line;              /* line edges matching source and activation */
  guint64 line_missed;       /* of those, dropped by line_miss_every */
  guint64 line_doubled;      /* of those, doubled by line_double_every */
  guint64 not_rendered;      /* triggers dropped: their light not rendered in time (lab_camera_fill.h) */
} DsLabTriggerStats;

/* renderer is borrowed and must outlive the camera. Renders the lighting states the
 * controller shows now before the camera appears (seconds for a wide kernel: lab_states.h).
 * Fails (G_IO_ERROR) when the fake camera cannot serve on the address (e.g. port 3956 in
 * use), DS_SIM_ERROR when a state cannot be rendered. */
DsLabCamera *ds_lab_camera_new (const DsLabCameraConfig *config, const DsRenderer *renderer,
                                DsLabIlluminationFunc illumination, gpointer user_data,
                                GError **error);
/* An edge at line input `line` (0..3). Non-blocking; any thread. */
void ds_lab_camera_line_edge (DsLabCamera *camera, guint line, gboolean rising);
void ds_lab_camera_trigger_stats (DsLabCamera *camera, DsLabTriggerStats *stats);
/* The lighting states rendered before the camera appeared, and how long that took. */
void ds_lab_camera_prepared (DsLabCamera *camera, guint *n_states, double *seconds);
guint64 ds_lab_camera_frames (DsLabCamera *camera);   /* frames filled so far */
gboolean ds_lab_camera_present (DsLabCamera *camera); /* FALSE while vanished */
void ds_lab_camera_free (DsLabCamera *camera);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsLabCamera, ds_lab_camera_free)

G_END_DECLS
