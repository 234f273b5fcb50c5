/* Room on the disk for a growing file: the free bytes of its filesystem, and a reserve file
 * (ballast) held next to it and given back when the writer has to close in a hurry.
 *
 * Why: a library that writes a file in place (HDF5) cannot be trusted after a write failed half
 * way (ENOSPC): its caches may hold blocks it believes written. So the writer checks the room
 * before each append and does not start one that cannot fit, and when a write fails anyway (the
 * disk filled between the check and the write) it releases the reserve, so that closing the file
 * (which flushes the library's metadata) has room to succeed. Any thread; each call blocks on
 * the filesystem only briefly (statvfs, fallocate of a small file). */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

/* The reserve's size: more than HDF5 writes when it flushes its metadata and closes. */
#define DS_DISK_RESERVE_BYTES (1024 * 1024)

/* Bytes an unprivileged writer may still use on the filesystem holding `path` (a file or a
 * folder); G_MAXUINT64 when the filesystem does not say. */
guint64 ds_disk_free_bytes (const char *path);
/* The reserve file of `path`: ".BASENAME.reserve.tmp" in its folder (hidden and ".tmp", so the
 * spool's start-up removes one left by a crash). */
char *ds_disk_reserve_path (const char *path);
/* Creates (or keeps) the reserve with its blocks allocated. FALSE, with nothing left behind,
 * when there is no room for it. */
gboolean ds_disk_reserve_take (const char *reserve_path);
/* Removes the reserve (no error when it is absent). */
void ds_disk_reserve_release (const char *reserve_path);

G_END_DECLS
