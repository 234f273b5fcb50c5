/* CSV as RFC 4180 has it, for the tables descatterctl writes and reads back (study.csv): a
 * field holding a comma, a double quote, a CR or an LF (or starting or ending with a space,
 * which some readers trim) is written between double quotes with its quotes doubled; anything
 * else is written as it is. Reading undoes exactly that, so that a scene file named
 * `a, "b".scene` reads back as itself in Python's csv module, pandas, a spreadsheet and here. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

/* Appends one field to `row`, quoted when it needs to be (no separator). */
void ds_csv_append_field (GString *row, const char *text);

/* One record of a CSV text: its fields and the line it starts on (1-based). */
typedef struct {
  GStrv fields;
  guint line;
} DsCsvRecord;

/* Every record of `text` (LF or CRLF line ends; a final line end optional; empty lines
 * skipped), as DsCsvRecord in a GArray that frees them. NULL with G_FILE_ERROR_INVAL naming
 * `where` and the line on a quote left open or a quote inside an unquoted field. */
GArray *ds_csv_parse (const char *text, const char *where, GError **error);

G_END_DECLS
