/* Compares a result message (transmissive, scattered, mask payloads) with the simulator's
 * noise-free truth, against an error bound derived from the sensor's noise model. */
#pragma once
#include "daemon/protocol/client.h"
#include "drivers/sim/renderer.h"
#include "drivers/sim/scene.h"

typedef struct {
  double rms_transmissive, allowed_transmissive; /* DN, over valid pixels */
  double rms_scattered, allowed_scattered;
  guint64 valid, pixels;
} TruthCheck;

/* The data of the result's payload `name`, asserting its dtype ("f32", "u8") and size; the
 * test aborts when the result has no such payload. */
const void *truth_payload (const DsMessage *m, const char *name, const char *dtype, guint w, guint h);

/* The truth for this exposure/gain must have the result's size. */
void truth_check (const DsMessage *m, const DsScene *scene, const DsImage *truth_t,
                  const DsImage *truth_g, TruthCheck *out);
gboolean truth_check_passed (const TruthCheck *c);

/* A test program's scene (the program aborts if it does not load) and its noise-free
 * components at the scene's default exposure and gain 0, to check results against. */
void truth_scene_load (const char *scene_path, DsScene **scene, DsImage **truth_t, DsImage **truth_g);
void truth_scene_free (DsScene *scene, DsImage *truth_t, DsImage *truth_g);

/* One `capture` (args may be NULL) checked against the truth: TRUE when the set came back and
 * equals the truth within the noise bound (a set that comes back wrong fails the test); FALSE
 * when the daemon failed it, with a message (never empty) and its wire code, which *message
 * and *code get (each may be NULL; *message is the caller's). Both outcomes are logged with the
 * time the capture took. */
gboolean truth_capture (DsClient *c, JsonObject *args, const DsScene *scene, const DsImage *truth_t,
                        const DsImage *truth_g, char **message, const char **code);
