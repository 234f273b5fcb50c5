/* The Henyey-Greenstein phase function in mu = cos(theta), normalized over mu in [-1, 1]:
 * p(mu) = (1 - g^2) / (2 (1 + g^2 - 2 g mu)^(3/2)); its mean cosine is g. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

double ds_hg_pdf (double g, double mu);
/* P(cos theta <= mu), closed form. */
double ds_hg_cdf (double g, double mu);
/* cos(theta) by inverting the CDF at a uniform xi in [0, 1). */
double ds_hg_sample_cos (double g, double xi);
/* P(cos theta > 0): the forward-scattered fraction. */
double ds_hg_forward_fraction (double g);

G_END_DECLS
