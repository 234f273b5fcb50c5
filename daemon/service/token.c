#include "daemon/service/token.h"

#include <string.h>

gboolean
ds_token_equal (const char *expected, const char *given)
{
  gsize n = strlen (expected), m = given ? strlen (given) : 0;
  guint8 diff = (guint8) (n != m);
  for (gsize i = 0; i < n; i++)
    diff |= (guint8) (expected[i] ^ (i < m ? given[i] : 0));
  return diff == 0;
}
