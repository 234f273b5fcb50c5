#include "daemon/ctl/csv.h"

#include <string.h>

void
ds_csv_append_field (GString *row, const char *text)
{
  gsize n = strlen (text);
  gboolean quote = strpbrk (text, ",\"\r\n") != NULL || (n > 0 && (text[0] == ' ' || text[n - 1] == ' '));
  if (!quote) {
    g_string_append (row, text);
    return;
  }
  g_string_append_c (row, '"');
  for (const char *c = text; *c; c++) {
    if (*c == '"')
      g_string_append_c (row, '"');
    g_string_append_c (row, *c);
  }
  g_string_append_c (row, '"');
}

static void
clear_record (gpointer data)
{
  g_strfreev (((DsCsvRecord *) data)->fields);
}

/* Reads one field at *c into `field` (quoted: quotes doubled inside, line ends kept; or plain)
 * and leaves *c on what follows it: a comma, a line end or the end. */
static gboolean
read_field (const char **c, guint *line, GString *field, const char *where, GError **error)
{
  const char *p = *c;
  if (*p != '"') {
    for (; *p && *p != ',' && *p != '\n' && !(*p == '\r' && p[1] == '\n'); p++) {
      if (*p == '"') {
        g_set_error (error, G_FILE_ERROR, G_FILE_ERROR_INVAL,
                     "%s:%u: a double quote inside an unquoted field (quote the field, double the quote)", where,
                     *line);
        return FALSE;
      }
      g_string_append_c (field, *p);
    }
    *c = p;
    return TRUE;
  }
  guint open_line = *line;
  for (p++;; p++) {
    if (*p == '\0') {
      g_set_error (error, G_FILE_ERROR, G_FILE_ERROR_INVAL, "%s:%u: a quoted field is never closed", where,
                   open_line);
      return FALSE;
    }
    if (*p == '"' && p[1] == '"')
      p++;
    else if (*p == '"')
      break;
    *line += *p == '\n';
    g_string_append_c (field, *p);
  }
  p++;
  if (*p != ',' && *p != '\n' && *p != '\0' && !(*p == '\r' && p[1] == '\n')) {
    g_set_error (error, G_FILE_ERROR, G_FILE_ERROR_INVAL, "%s:%u: text after a quoted field's closing quote",
                 where, *line);
    return FALSE;
  }
  *c = p;
  return TRUE;
}

GArray *
ds_csv_parse (const char *text, const char *where, GError **error)
{
  g_autoptr (GArray) records = g_array_new (FALSE, FALSE, sizeof (DsCsvRecord));
  g_array_set_clear_func (records, clear_record);
  g_autoptr (GPtrArray) fields = g_ptr_array_new_with_free_func (g_free);
  guint line = 1, record_line = 1;
  const char *c = text;
  while (*c) {
    g_autoptr (GString) field = g_string_new (NULL);
    if (!read_field (&c, &line, field, where, error))
      return NULL;
    g_ptr_array_add (fields, g_string_free (g_steal_pointer (&field), FALSE));
    if (*c == ',') {
      c++;
      if (*c == '\0' || *c == '\n' || (*c == '\r' && c[1] == '\n'))
        g_ptr_array_add (fields, g_strdup (""));  /* a last field left empty */
      else
        continue;
    }
    /* The record ends here; an empty line (one empty field) is no record. */
    if (!(fields->len == 1 && *(const char *) g_ptr_array_index (fields, 0) == '\0')) {
      g_ptr_array_add (fields, NULL);
      DsCsvRecord r = { .fields = (GStrv) g_ptr_array_free (g_steal_pointer (&fields), FALSE), .line = record_line };
      g_array_append_val (records, r);
      fields = g_ptr_array_new_with_free_func (g_free);
    } else
      g_ptr_array_set_size (fields, 0);
    if (*c)
      c += *c == '\r' ? 2 : 1;
    record_line = ++line;
  }
  return g_steal_pointer (&records);
}
