/* Writes sample results (sample_result.h) for test_output_files.py:
 *   write_sample files DIR KINDS SETS   the result files of sets 0..SETS-1 into DIR
 *   write_sample run PATH SETS [hang]   a growing HDF5 run of SETS sets; prints "appended K"
 *                                       after each; with "hang", waits to be killed instead
 *                                       of closing the run */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "daemon/output/hdf5_run.h"
#include "daemon/output/result_files.h"
#include "sample_result.h"

int
main (int argc, char **argv)
{
  g_autoptr (GError) error = NULL;
  if (argc >= 5 && strcmp (argv[1], "files") == 0) {
    guint kinds = 0;
    if (!ds_file_kinds_parse (argv[3], &kinds, &error))
      return fprintf (stderr, "%s\n", error->message), 2;
    kinds |= DS_FILES_PHASES;
    for (guint set = 0; set < (guint) atoi (argv[4]); set++) {
      g_autoptr (SampleResult) s = sample_result_new (24, 10, set, TRUE, TRUE);
      g_autofree char *stem = ds_result_stem (s->planes.meta);
      if (!ds_result_write_files (&s->planes, argv[2], stem, kinds, NULL, &error))
        return fprintf (stderr, "%s\n", error->message), 1;
    }
    return 0;
  }
  if (argc >= 4 && strcmp (argv[1], "run") == 0) {
    guint sets = (guint) atoi (argv[3]);
    gboolean hang = argc >= 5 && strcmp (argv[4], "hang") == 0;
    g_autoptr (SampleResult) first = sample_result_new (24, 10, 0, TRUE, FALSE);
    DsHdf5Run *run = ds_hdf5_run_open (argv[2], &first->planes, &error);
    if (!run)
      return fprintf (stderr, "%s\n", error->message), 1;
    for (guint set = 0; set < sets; set++) {
      g_autoptr (SampleResult) s = sample_result_new (24, 10, set, set % 2 == 0, FALSE);
      if (!ds_hdf5_run_append (run, &s->planes, &error))
        return fprintf (stderr, "%s\n", error->message), 1;
      printf ("appended %u\n", set + 1);
      fflush (stdout);
    }
    if (hang)
      for (;;)
        g_usleep (G_USEC_PER_SEC);
    if (!ds_hdf5_run_close (run, &error))
      return fprintf (stderr, "%s\n", error->message), 1;
    return 0;
  }
  fprintf (stderr, "usage: write_sample files DIR KINDS SETS | run PATH SETS [hang]\n");
  return 2;
}
