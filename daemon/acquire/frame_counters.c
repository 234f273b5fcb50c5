/* Frame accounting: what happened to every frame the camera delivered (folded, or dropped
 * with one reason), and the device events around them. Plain arithmetic on caller-owned
 * structs: no locking, any thread (the totals are summed under the sequencer's lock). */
#include "daemon/acquire/frame_counters.h"

static const char *const drop_names[DS_DROP_N_REASONS] = {
  [DS_DROP_INCOMPLETE] = "incomplete",   [DS_DROP_FRAME_GAP] = "frame_gap",
  [DS_DROP_WRONG_PHASE] = "wrong_phase", [DS_DROP_STALE] = "stale",
  [DS_DROP_UNVERIFIABLE] = "unverifiable", [DS_DROP_ABORTED] = "aborted",
  [DS_DROP_PREVIEW] = "preview",
};

const char *
ds_drop_reason_name (DsDropReason reason)
{
  return (guint) reason < DS_DROP_N_REASONS ? drop_names[reason] : "unknown";
}

void
ds_frame_counters_drop (DsFrameCounters *c, DsDropReason reason, guint64 n)
{
  g_return_if_fail ((guint) reason < DS_DROP_N_REASONS);
  c->dropped += n;
  c->by_reason[reason] += n;
}

void
ds_frame_counters_abort_rest (DsFrameCounters *c)
{
  ds_frame_counters_drop (c, DS_DROP_ABORTED, c->acquired - c->dropped);
}

void
ds_frame_counters_fold_rest (DsFrameCounters *c)
{
  c->folded = c->acquired - c->dropped;
}

void
ds_frame_counters_add (DsFrameCounters *total, const DsFrameCounters *part)
{
  total->acquired += part->acquired;
  total->folded += part->folded;
  total->dropped += part->dropped;
  for (guint i = 0; i < DS_DROP_N_REASONS; i++)
    total->by_reason[i] += part->by_reason[i];
  total->retries += part->retries;
  total->timeouts += part->timeouts;
  total->device_errors += part->device_errors;
  total->unverified += part->unverified;
}

JsonNode *
ds_frame_counters_to_json (const DsFrameCounters *c)
{
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "acquired");
  json_builder_add_int_value (b, (gint64) c->acquired);
  json_builder_set_member_name (b, "folded");
  json_builder_add_int_value (b, (gint64) c->folded);
  json_builder_set_member_name (b, "retries");
  json_builder_add_int_value (b, (gint64) c->retries);
  json_builder_set_member_name (b, "timeouts");
  json_builder_add_int_value (b, (gint64) c->timeouts);
  json_builder_set_member_name (b, "device_errors");
  json_builder_add_int_value (b, (gint64) c->device_errors);
  json_builder_set_member_name (b, "unverified");
  json_builder_add_int_value (b, (gint64) c->unverified);
  json_builder_set_member_name (b, "dropped");
  json_builder_add_int_value (b, (gint64) c->dropped);
  json_builder_set_member_name (b, "dropped_by_reason");
  json_builder_begin_object (b);
  for (guint i = 0; i < DS_DROP_N_REASONS; i++) {
    json_builder_set_member_name (b, drop_names[i]);
    json_builder_add_int_value (b, (gint64) c->by_reason[i]);
  }
  json_builder_end_object (b);
  json_builder_end_object (b);
  return json_builder_get_root (b);
}
